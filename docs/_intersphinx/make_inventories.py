"""Write the intersphinx inventories of docs/_intersphinx/ (``python docs/_intersphinx/make_inventories.py``).

The documentation builds offline (CI and the developers' machines reach package registries only),
so Sphinx cannot download the ``objects.inv`` of NumPy, SciPy, scikit-learn, Dask, Matplotlib,
pandas and Python (and of pooch and scikit-bio, which some docstrings name). This script writes them from what is installed here: for each project it walks
the public names of the modules listed in :data:`PROJECTS` (the modules shapelib's documentation
refers to), imports each one to know what it is (module, class, exception, function, method or
data) and records it with the page that project's own Sphinx site gives it (each site names its
API pages by one rule: :func:`numpy_page`, ...). The result is a standard inventory (format
version 2, what ``sphinx.ext.intersphinx`` reads and ``sphinx-build`` writes), one per project,
headed by the installed version; ``docs/conf.py`` points ``intersphinx_mapping`` at them with the
projects' real URLs, so the links lead to the projects' stable documentation.

Re-run it when a docstring refers to a name of a module not walked yet (add the module below; the
nitpicky build says which reference did not resolve) or when the dependencies move on. The output
is deterministic (sorted, no dates): running it twice gives the same files.
"""

from __future__ import annotations

import importlib
import inspect
import sys
import types
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent


def numpy_page(name: str, role: str) -> str:
    if name == "numpy" or role == "py:module":
        return f"reference/index.html#module-{name}"
    if name.startswith("numpy.random.Generator") or name == "numpy.random.default_rng":
        if name.count(".") == 3:  # a method of Generator
            return f"reference/random/generated/{name}.html#{name}"
        return f"reference/random/generator.html#{name}"
    if name.startswith("numpy.random."):
        return f"reference/random/generated/{name}.html#{name}"
    if name in SCALARS:
        return f"reference/arrays.scalars.html#{name}"
    return f"reference/generated/{name}.html#{name}"


SCALARS = {f"numpy.{t}" for t in ("float64", "float32", "int64", "int32", "bool_", "integer", "floating",
                                  "number", "generic", "complex128", "intp", "uint8")}


def scipy_page(name: str, role: str) -> str:
    if role == "py:module":
        return f"reference/{name.removeprefix('scipy.')}.html#module-{name}"
    return f"reference/generated/{name}.html#{name}"


def sklearn_page(name: str, role: str) -> str:
    if role == "py:module":
        return f"api/{name}.html#module-{name}"
    if role in ("py:method", "py:attribute"):  # on the class's page
        return f"modules/generated/{name.rsplit('.', 1)[0]}.html#{name}"
    return f"modules/generated/{name}.html#{name}"


def pandas_page(name: str, role: str) -> str:
    if role == "py:module":
        return "reference/index.html#module-pandas"
    return f"reference/api/{name}.html#{name}"


def dask_page(name: str, role: str) -> str:
    if role == "py:module":
        return f"array-api.html#module-{name}"
    return f"generated/{name}.html#{name}"


def distributed_page(name: str, role: str) -> str:
    return f"api.html#{'module-' if role == 'py:module' else ''}{name}"


def pooch_page(name: str, role: str) -> str:
    return "api/index.html#module-pooch" if role == "py:module" else f"api/generated/{name}.html#{name}"


def skbio_page(name: str, role: str) -> str:
    return f"generated/{name}.html#{name}" if role != "py:module" else f"{name.replace('.', '/')}.html#module-{name}"


def matplotlib_page(name: str, role: str) -> str:
    if role == "py:module":
        return f"api/{name.removeprefix('matplotlib.')}_api.html#module-{name}"
    if name == "matplotlib.axes.Axes":
        return f"api/axes_api.html#{name}"
    if role in ("py:method", "py:attribute") and not name.startswith("matplotlib.axes.Axes."):
        return f"api/_as_gen/{name.rsplit('.', 1)[0]}.html#{name}"
    return f"api/_as_gen/{name}.html#{name}"


BUILTIN_TYPES = {"dict", "list", "str", "tuple", "set", "frozenset", "bytes", "range", "memoryview"}


def python_page(name: str, role: str) -> str:
    if "." not in name:  # builtins
        if role == "py:exception":
            return f"library/exceptions.html#{name}"
        if name in BUILTIN_TYPES:
            return f"library/stdtypes.html#{name}"
        if name == "None":
            return "library/constants.html#None"
        return f"library/functions.html#{name}"
    module = name.split(".")[0] if role != "py:module" else name
    if name.startswith("concurrent.futures"):
        module = "concurrent.futures"
    if name.startswith("os.path"):
        module = "os.path"
    if name.startswith("importlib.resources"):
        module = "importlib.resources"
    return f"library/{module}.html#{'module-' if role == 'py:module' else ''}{name}"


#: project: (URL of its documentation, page rule, modules whose public names are recorded,
#: classes whose public methods and attributes are recorded)
PROJECTS = {
    "python": ("https://docs.python.org/3/", python_page,
               ["builtins", "pathlib", "os", "os.path", "warnings", "enum", "dataclasses", "concurrent.futures",
                "collections.abc", "typing", "functools", "json", "signal", "multiprocessing", "threading",
                "logging", "io", "csv", "argparse", "subprocess", "tempfile", "contextlib",
                "importlib.resources"],
               ["pathlib.Path", "concurrent.futures.Executor", "concurrent.futures.Future", "dict", "list",
                "str", "enum.Enum", "warnings.catch_warnings", "threading.Event"]),
    "numpy": ("https://numpy.org/doc/stable/", numpy_page,
              ["numpy", "numpy.linalg", "numpy.random", "numpy.fft", "numpy.testing", "numpy.lib.npyio"],
              ["numpy.ndarray", "numpy.random.Generator", "numpy.dtype"]),
    "scipy": ("https://docs.scipy.org/doc/scipy/", scipy_page,
              ["scipy.linalg", "scipy.optimize", "scipy.spatial", "scipy.spatial.distance", "scipy.stats",
               "scipy.cluster.hierarchy", "scipy.integrate", "scipy.interpolate", "scipy.special",
               "scipy.sparse", "scipy.ndimage", "scipy.sparse.linalg"],
              ["scipy.optimize.OptimizeResult", "scipy.spatial.KDTree", "scipy.spatial.cKDTree"]),
    "sklearn": ("https://scikit-learn.org/stable/", sklearn_page,
                ["sklearn.decomposition", "sklearn.manifold", "sklearn.neighbors", "sklearn.model_selection",
                 "sklearn.metrics", "sklearn.cluster", "sklearn.linear_model", "sklearn.pipeline",
                 "sklearn.preprocessing", "sklearn.base"],
                ["sklearn.decomposition.PCA", "sklearn.manifold.MDS", "sklearn.neighbors.KNeighborsClassifier",
                 "sklearn.base.BaseEstimator", "sklearn.base.TransformerMixin"]),
    "pandas": ("https://pandas.pydata.org/docs/", pandas_page,
               ["pandas"],
               ["pandas.DataFrame", "pandas.Series", "pandas.Index", "pandas.Categorical"]),
    "dask": ("https://docs.dask.org/en/stable/", dask_page,
             ["dask", "dask.array", "dask.bag", "dask.delayed"],
             ["dask.array.Array"]),
    "distributed": ("https://distributed.dask.org/en/stable/", distributed_page,
                    ["distributed"],
                    ["distributed.Client", "distributed.LocalCluster", "distributed.Future"]),
    "pooch": ("https://www.fatiando.org/pooch/latest/", pooch_page, ["pooch"], []),
    "skbio": ("https://scikit.bio/docs/latest/", skbio_page, ["skbio.stats.distance", "skbio.stats.ordination"], []),
    "matplotlib": ("https://matplotlib.org/stable/", matplotlib_page,
                   ["matplotlib.pyplot", "matplotlib.figure", "matplotlib.axes", "matplotlib.animation",
                    "matplotlib.colors", "matplotlib.collections", "matplotlib.lines", "matplotlib.patches",
                    "matplotlib.cm", "matplotlib.tri"],
                   ["matplotlib.figure.Figure", "matplotlib.axes.Axes", "matplotlib.animation.FuncAnimation",
                    "matplotlib.colors.Colormap", "matplotlib.lines.Line2D"]),
}


def role_of(obj) -> str:
    if isinstance(obj, types.ModuleType):
        return "py:module"
    if inspect.isclass(obj):
        return "py:exception" if issubclass(obj, BaseException) else "py:class"
    if callable(obj):
        return "py:function"
    return "py:data"


def public_names(module) -> list[str]:
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in dir(module) if not n.startswith("_")]
    return sorted(n for n in names if isinstance(n, str) and not n.startswith("_"))


def _resolve(dotted: str):
    if "." not in dotted:
        import builtins

        return getattr(builtins, dotted)
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def entries(project: str) -> dict[str, str]:
    """``{name: role}`` of the project's recorded objects."""
    _, _, modules, classes = PROJECTS[project]
    out: dict[str, str] = {}
    root = project if project != "python" else None
    for modname in modules:
        module = importlib.import_module(modname)
        if modname != "builtins":
            out[modname] = "py:module"
        for name in public_names(module):
            try:
                obj = getattr(module, name)
            except (AttributeError, ImportError):  # experimental or removed names served lazily
                continue
            role = role_of(obj)
            if role == "py:module":
                continue
            owner = getattr(obj, "__module__", None) or ""
            if root and not (owner.startswith(root) or isinstance(obj, (int, float, str, tuple))):
                continue  # a name another project defines (numpy's re-exports of builtins...)
            full = name if modname == "builtins" else f"{modname}.{name}"
            out[full] = role
    for cls_name in classes:
        cls = _resolve(cls_name)
        out[cls_name] = role_of(cls)
        for name, member in inspect.getmembers(cls):
            if name.startswith("_"):
                continue
            kind = "py:attribute" if isinstance(member, property) or not callable(member) else "py:method"
            out[f"{cls_name}.{name}"] = kind
    return out


def inventory(project: str) -> bytes:
    url, page, _, _ = PROJECTS[project]
    version = sys.version.split()[0] if project == "python" else importlib.import_module(project).__version__
    header = (f"# Sphinx inventory version 2\n# Project: {project}\n# Version: {version}\n"
              "# The remainder of this file is compressed using zlib.\n").encode()
    lines = []
    records = sorted(entries(project).items())
    if project == "python":  # Python's documentation describes many classes as functions (functools.partial)
        records = sorted(records + [(n, "py:function") for n, r in records if r == "py:class"])
    for name, role in records:
        uri = page(name, role)
        if uri.endswith("#" + name):
            uri = uri[: -len(name)] + "$"  # Sphinx's shorthand for "the anchor is the name"
        lines.append(f"{name} {role} 1 {uri} -\n")
    lines += [f"{term} std:term -1 glossary.html#term-{term.replace(' ', '-')} -\n" for term in GLOSSARY.get(project, ())]
    return header + zlib.compress("".join(lines).encode(), 9)


GLOSSARY = {"numpy": ("array_like",), "python": ("iterable", "path-like object", "file object", "callable")}


def main() -> None:
    for project in PROJECTS:
        data = inventory(project)
        (HERE / f"{project}.inv").write_bytes(data)
        n = zlib.decompress(data.split(b"zlib.\n", 1)[1]).count(b"\n")
        print(f"{project}: {n} objects -> docs/_intersphinx/{project}.inv")


if __name__ == "__main__":
    main()
