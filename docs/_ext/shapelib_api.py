"""The API reference's one table: every public name, its area, and the paper's equation it implements.

:data:`AREAS` is the only list of documented names. From it ``make docs`` writes (into
``docs/api/reference/``, not committed) one page per area — its introduction, the modules whose
docstrings carry the area's mathematics, and an autosummary table of its names, each with its own
page — the toctree that puts the areas in the sidebar, one page per module that renders the
module's docstring, and the map from the paper's equations to functions and modules
(``docs/api/reference/equations.rst``, the only copy of that map). ``tests/test_docs.py`` reads the
same table: every public name has an entry, and the built page of every name with an equation
shows a rendered formula.

Adding a public name is one line in its area: ``"module.name"`` or ``"module.name  (eq)"`` where
``module`` is where it is documented (``shapelib`` for the top-level names) and ``eq`` the paper's
equation numbers (``5``, ``8-12``, ``23-26``). A new area is one more :class:`Area`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
OUT = DOCS / "api" / "reference"


@dataclass(frozen=True)
class Area:
    slug: str
    title: str
    intro: str
    #: modules whose docstrings carry the area's mathematics and design (each gets a page)
    modules: tuple[str, ...]
    #: one line per public name: ``module.name`` and optionally ``(equation numbers)``
    names: str


AREAS = (
    Area("shapes", "Shapes and densities",
         "A shape is a ``(K, d)`` array of landmarks in correspondence; collections of shapes are "
         "``(N, K, d)`` arrays. shapelib represents a shape by the Gaussian mixture of eq. (5), one "
         "isotropic component of variance σ² on each landmark.",
         ("shapelib", "shapelib.geometry.gmm"),
         """
         shapelib.gmm_density          (5)
         shapelib.l2_distance          (5)
         """),
    Area("metrics", "Metrics",
         "The Fisher–Rao metric (eq. 6, by quadrature) and the closed-form α-order entropy metric "
         "(eq. 22) of the mixture, as metric tensors on the landmark coordinates, and as the path "
         "solver sees them: the energy, gradient and Hessian of a discrete path.",
         ("shapelib.geometry.metrics", "shapelib.geometry.quadrature", "shapelib.solver.path_metric"),
         """
         shapelib.fisher_rao_metric          (6)
         shapelib.fisher_rao_quadratic_form  (6)
         shapelib.alpha_metric               (22)
         shapelib.alpha_quadratic_form       (22)
         shapelib.path_metric
         shapelib.PathMetric
         shapelib.AlphaPathMetric            (22)
         shapelib.FisherRaoPathMetric        (6)
         """),
    Area("geodesics", "Geodesics and certified distances",
         "Geodesics (eqs. 8–12) are the deformations between two shapes and their lengths the "
         "shape distances. A bracket certifies ``lower ≤ d ≤ upper`` to a relative width; the "
         "closed-form lower bounds come as whole matrices for populations.",
         ("shapelib.solver.geodesic", "shapelib.solver.bracket", "shapelib.solver.result",
          "shapelib.geometry.bound_matrices", "shapelib.comparison.warp"),
         """
         shapelib.geodesic                   (8-12)
         shapelib.GeodesicResult
         shapelib.GeodesicWarning
         shapelib.path_length                (8)
         shapelib.fisher_rao_lower_bound
         shapelib.distance_bracket
         shapelib.DistanceBracket
         shapelib.StopReason
         shapelib.BracketStopReason
         shapelib.alpha_bound_matrix
         shapelib.fisher_rao_bound_matrix
         shapelib.geodesics
         shapelib.distance_brackets
         shapelib.batched_lengths
         shapelib.bound_matrix_sweep
         shapelib.extrinsic_warp             (23-26)
         """),
    Area("comparison", "Comparison distances",
         "The distances Table I compares the information metrics with — Procrustes, Hausdorff, "
         "thin-plate and Wendland spline bending energies, landmark diffeomorphisms (eq. 3, "
         "Camion–Younes) — and the one entry point that computes any registered metric; missing "
         "landmarks estimated and semilandmarks slid along their curves (thin-plate spline).",
         ("shapelib.distances", "shapelib.comparison.splines", "shapelib.comparison.diffeomorphism",
          "shapelib.comparison.hausdorff", "shapelib.comparison.missing", "shapelib.geometry.semilandmarks"),
         """
         shapelib.distance
         shapelib.pair_record
         shapelib.register_metric
         shapelib.metric_info
         shapelib.MetricInfo
         shapelib.procrustes_distance
         shapelib.hausdorff_distance
         shapelib.tps_bending_energy
         shapelib.wendland_bending_energy
         shapelib.landmark_diffeomorphism    (3)
         shapelib.diffeomorphism_warp        (3)
         shapelib.estimate_missing
         shapelib.MissingEstimate
         shapelib.tps_map
         shapelib.slide_semilandmarks
         shapelib.SlideResult
         shapelib.curve_sliders
         shapelib.bending_energy_matrix
         """),
    Area("scale", "σ² and scale",
         "σ² is a squared length in the landmarks' units: these bring shapes to the study's scale, "
         "measure σ against the landmark spacing and estimate σ² from the data "
         "(:doc:`/guide/scale`).",
         ("shapelib.geometry.scale", "shapelib.geometry.sigma2"),
         """
         shapelib.to_centroid_size
         shapelib.landmark_spacing
         shapelib.sigma_ratio
         shapelib.ScaleWarning
         shapelib.estimate_sigma2
         shapelib.Sigma2Estimate
         """),
    Area("statistics", "Statistics",
         "Intrinsic statistics on the information manifolds — log and exp maps of the discrete "
         "geodesic, parallel transport, the Fréchet mean, tangent PCA, geodesic regression, a permutation test of a "
         "difference in mean shape — tests and ordinations on distance matrices, and geomorph's "
         "analyses of Procrustes coordinates: linear models, allometry, disparity, two-block PLS, modularity, "
         "bilateral symmetry, phenotypic trajectories and global integration. "
         "``frechet_mean``, ``tangent_pca``, ``geodesic_regression`` and ``mean_difference_test`` "
         "are the same functions as ``shapelib.statistics.frechet_mean`` and so on, documented "
         "once, under their top-level names; their log maps run on the engine's workers "
         "(``n_jobs``, ``client``, ``scheduler``) or on any ``executor``.",
         ("shapelib.solver.logexp", "shapelib.solver.transport", "shapelib.statistics", "shapelib.statistics.frechet",
          "shapelib.statistics.tangent_pca", "shapelib.statistics.regression", "shapelib.statistics.group",
          "shapelib.statistics.distance_based", "shapelib.statistics.sweep", "shapelib.statistics.linear_model",
          "shapelib.statistics.allometry", "shapelib.statistics.disparity", "shapelib.statistics.pls",
          "shapelib.statistics.modularity", "shapelib.statistics.symmetry",
          "shapelib.statistics.trajectory", "shapelib.statistics.integration"),
         """
         shapelib.log_map
         shapelib.exp_map
         shapelib.tangent_space
         shapelib.parallel_transport
         shapelib.frechet_mean
         shapelib.tangent_pca
         shapelib.TangentPCA
         shapelib.geodesic_regression
         shapelib.mean_difference_test
         shapelib.statistics.FrechetMeanResult
         shapelib.statistics.procrustes_mean
         shapelib.statistics.TangentPCAResult
         shapelib.statistics.GeodesicRegressionResult
         shapelib.statistics.MeanDifferenceResult
         shapelib.statistics.permanova
         shapelib.statistics.PermanovaResult
         shapelib.statistics.knn_loo_accuracy
         shapelib.statistics.KnnResult
         shapelib.statistics.mantel_test
         shapelib.statistics.classical_mds
         shapelib.statistics.gower_centered
         shapelib.statistics.as_distance_matrix
         shapelib.statistics.permanova_sweep
         shapelib.statistics.knn_sweep
         shapelib.statistics.min_p_adjusted
         shapelib.statistics.SweepTest
         shapelib.shape_lm
         shapelib.ShapeLinearModel
         shapelib.procrustes_coordinates
         shapelib.allometry
         shapelib.AllometryResult
         shapelib.morphological_disparity
         shapelib.DisparityResult
         shapelib.two_block_pls
         shapelib.PLSResult
         shapelib.modularity_test
         shapelib.ModularityResult
         shapelib.bilateral_symmetry
         shapelib.SymmetryResult
         shapelib.trajectory_analysis
         shapelib.TrajectoryResult
         shapelib.global_integration
         shapelib.GlobalIntegrationResult
         shapelib.holm_adjust
         """),
    Area("engine", "Engine",
         "Distance matrices at population scale: pairs in blocks, as Dask tasks or in process, "
         "kept in a resumable zarr store (:doc:`/guide/population`).",
         ("shapelib.pairwise",),
         """
         shapelib.pairwise_distances
         shapelib.pairwise.compute_pairwise
         shapelib.pairwise.PairwiseResult
         shapelib.pairwise.BlockProgress
         shapelib.pairwise.engine_executor
         shapelib.pairwise.PairError
         shapelib.pairwise.open_store
         shapelib.pairwise.local_cluster
         shapelib.pairwise.default_block_size
         shapelib.pairwise.block_pairs
         shapelib.pairwise.compute_block
         shapelib.pairwise.ARRAYS
         """),
    Area("io", "Input, output and datasets",
         "Landmark files — tpsDig ``.tps``, CSV (wide or long), NumPy ``.npy``/``.npz``, geomorph's "
         "``p × k × n`` arrays and sliding-semilandmark tables (``curveslide.csv``) — the input errors "
         "every entry point raises, and the study's raw data, fetched and checked against the "
         "registry's checksums or read from ``SHAPELIB_DATA_DIR``.",
         ("shapelib.io", "shapelib.datasets"),
         """
         shapelib.InputError
         shapelib.io.read_landmarks
         shapelib.io.write_landmarks
         shapelib.io.read_tps
         shapelib.io.write_tps
         shapelib.io.read_csv
         shapelib.io.write_csv
         shapelib.io.read_npy
         shapelib.io.write_npy
         shapelib.io.from_pkn
         shapelib.io.to_pkn
         shapelib.io.FORMATS
         shapelib.io.NEGATIVE_COORDINATES_COMMENT
         shapelib.read_point_sets
         shapelib.write_point_set
         shapelib.read_sliders
         shapelib.datasets.load_corpus_callosum
         shapelib.datasets.load_adhd200
         shapelib.datasets.load_fish2d
         shapelib.datasets.load_beijing
         shapelib.datasets.load_tps_rpm
         shapelib.datasets.load_tps_rpm_case
         shapelib.datasets.TPS_RPM_LEVELS
         shapelib.datasets.load_mpeg7
         shapelib.datasets.mpeg7_classes
         shapelib.datasets.MPEG7
         shapelib.datasets.load_cpd_fish
         shapelib.datasets.load_gmmreg_fish
         shapelib.datasets.mpeg7_names
         shapelib.datasets.load_mpeg7_image
         shapelib.datasets.mpeg7_boundary
         shapelib.datasets.mpeg7_landmarks
         shapelib.datasets.registry
         shapelib.datasets.fetch
         shapelib.datasets.data_checksums
         shapelib.datasets.DATA_DIR_ENV
         shapelib.datasets.CC_PAPER_IDS
         """),
    Area("plotting", "Plotting",
         "Figures of shapes, geodesics, deformation grids, mean shapes and their modes (Matplotlib).",
         ("shapelib.plotting",),
         """
         shapelib.plotting.plot_trajectories
         shapelib.plotting.plot_metric_panels
         shapelib.plotting.plot_geodesic
         shapelib.plotting.parse_links
         shapelib.plotting.animate_geodesic
         shapelib.plotting.outline
         shapelib.plotting.plot_shapes_along
         shapelib.plotting.deformation_grid
         shapelib.plotting.plot_deformation
         shapelib.plotting.plot_mean
         shapelib.plotting.plot_modes
         shapelib.plotting.plot_mean_difference
         shapelib.plotting.plot_scores
         """),
    Area("registration", "Point sets and registration",
         "Rigid alignment of landmark shapes — Procrustes superimposition, pose alignment with "
         "sizes kept — and the pose check of the metrics that compare shapes where they lie "
         "(:doc:`/guide/checks`). Shapes without landmarks: point sets of any sizes, their mixture "
         "densities compared across sizes, σ² by EM, alignment over every rotation, registration "
         "rigid to non-rigid (:doc:`/guide/pointsets`), outlines traced from silhouettes and "
         "retrieval modulo similarity (:doc:`/guide/retrieval`).",
         ("shapelib.geometry.procrustes", "shapelib.pointsets", "shapelib.pointsets.checks",
          "shapelib.pointsets.density", "shapelib.pointsets.pose", "shapelib.pointsets.em",
          "shapelib.pointsets.registration", "shapelib.pointsets.outline", "shapelib.pointsets.invariant",
          "shapelib.retrieval"),
         """
         shapelib.as_point_set
         shapelib.as_point_sets
         shapelib.density_inner
         shapelib.l2_distance_sq
         shapelib.hellinger_sq
         shapelib.bhattacharyya_affinity
         shapelib.density_distance
         shapelib.align
         shapelib.Pose
         shapelib.PoseSearchWarning
         shapelib.fit_mixture
         shapelib.MixtureFit
         shapelib.EMWarning
         shapelib.register
         shapelib.register_many
         shapelib.RegistrationResult
         shapelib.RegistrationWarning
         shapelib.trace_outline
         shapelib.resample_closed
         shapelib.outline_topology
         shapelib.invariant_distance
         shapelib.invariant_distance_matrix
         shapelib.InvariantDistance
         shapelib.normalise_points
         shapelib.bullseye
         shapelib.BullseyeScore
         shapelib.nearest_wrong
         shapelib.procrustes_outline_matrix
         shapelib.rerank
         shapelib.pose_align
         shapelib.PoseWarning
         shapelib.centroid_size
         shapelib.preshape
         shapelib.procrustes_align
         shapelib.generalized_procrustes
         """),
)

_LINE = re.compile(r"^(?P<module>[\w.]+)\.(?P<name>\w+)(?:\s+\((?P<eq>[\d\-–, ]+)\))?$")


@dataclass(frozen=True)
class Entry:
    module: str  # where it is documented
    name: str
    equations: str  # "" or "5", "8-12"
    area: Area

    @property
    def qualname(self) -> str:
        return f"{self.module}.{self.name}"

    @property
    def eq_text(self) -> str:
        return self.equations.replace("-", "–")


def entries() -> list[Entry]:
    """Every documented name, in the table's order."""
    out = []
    for area in AREAS:
        for line in area.names.strip().splitlines():
            m = _LINE.match(line.strip())
            if not m:
                raise ValueError(f"docs/_ext/shapelib_api.py, area {area.title!r}: cannot read {line.strip()!r}; "
                                 "write 'module.name' or 'module.name  (equations)'")
            out.append(Entry(m["module"], m["name"], m["eq"] or "", area))
    return out


def api_entries() -> dict[str, set[str]]:
    """``{module: names}`` of the documented names."""
    out: dict[str, set[str]] = {}
    for e in entries():
        out.setdefault(e.module, set()).add(e.name)
    return out


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def _summary(names: list[Entry], *, toctree: bool) -> list[str]:
    lines, module = [], None
    for e in names:
        if e.module != module:
            module = e.module
            lines += ["", f".. currentmodule:: {module}", "", ".. autosummary::"]
            lines += ["   :toctree: ../generated/" if toctree else "   :nosignatures:", ""]
        lines.append(f"   {e.name}")
    return lines


def defined_in(e: Entry) -> str:
    """The module that defines a documented name (``shapelib.geometry.gmm`` for ``shapelib.gmm_density``)."""
    import importlib

    obj = getattr(importlib.import_module(e.module), e.name)
    return getattr(obj, "__module__", e.module) if callable(obj) else e.module


def _public(module: str) -> bool:
    return not any(part.startswith("_") for part in module.split("."))


def all_modules() -> list[str]:
    """Every public module of shapelib (each gets a page that renders its docstring). A name defined
    in a private module (``shapelib._validate.InputError``) is listed on its public parent's page."""
    import pkgutil

    import shapelib

    names = {"shapelib"}
    for info in pkgutil.walk_packages(shapelib.__path__, "shapelib."):
        if _public(info.name) and info.name != "shapelib.__main__":
            names.add(info.name)
    names |= {defined_in(e) for e in entries() if _public(defined_in(e))}  # the home of a documented name
    return sorted(names)


def documented_objects() -> dict[int, str]:
    """``{id(object): documented qualified name}``: where a name's page is, whatever module path a
    docstring reaches it by (``shapelib.geometry.gmm.l2_distance`` is ``shapelib.l2_distance``)."""
    import importlib

    out = {}
    for e in entries():
        obj = getattr(importlib.import_module(e.module), e.name)
        if callable(obj):
            out.setdefault(id(obj), e.qualname)
    return out


def pages() -> dict[str, str]:
    """``{path relative to docs/api/reference: reST}`` of every generated page."""
    out: dict[str, str] = {}
    all_entries = entries()
    for area in AREAS:
        names = [e for e in all_entries if e.area is area]
        text = [_title(area.title), area.intro, ""]
        text += ["Modules: " + ", ".join(f":doc:`{m} <modules/{m}>`" for m in area.modules)
                 + " (their docstrings give the mathematics and the design).", ""]
        text += _summary(names, toctree=True)
        out[f"{area.slug}.rst"] = "\n".join(text) + "\n"
    documented = {e.qualname for e in all_entries}
    area_of = {m: a for a in AREAS for m in a.modules}
    for module in all_modules():
        area = area_of.get(module)
        here = [e for e in all_entries if defined_in(e) == module or defined_in(e).startswith(module + "._")]
        page = [":orphan:", "", _title(f"``{module}``")]
        # a module whose name is also a documented function's (shapelib.statistics.tangent_pca):
        # its docstring without a second object of that name
        page += [f".. module-docstring:: {module}" if module in documented else f".. automodule:: {module}", ""]
        if here:
            title = "Public names of this module" + (f" (area: {area.title})" if area else "")
            page += [title, "-" * len(title)]
            page += _summary(here, toctree=False)
        out[f"modules/{module}.rst"] = "\n".join(page) + "\n"
    # the equations of the paper and where each lives: the only copy of this map
    with_page = set(all_modules())
    rows = [e for e in all_entries if e.equations]
    eq = [_title("The paper's equations in the code"),
          "Each equation of Peter & Rangarajan (:doc:`/citing`) that shapelib implements, the public "
          "names that compute it and the module whose docstring derives it. Every page of these "
          "names shows the formula.", "",
          ".. list-table::", "   :header-rows: 1", "   :widths: 12 40 48", "",
          "   * - equation", "     - implemented by", "     - derived in"]
    for e in sorted(rows, key=lambda e: (int(re.split(r"\D", e.equations)[0]), e.qualname)):
        home = defined_in(e)
        eq += [f"   * - eq. ({e.eq_text})", f"     - :obj:`{e.qualname}`",
               f"     - :doc:`{home} <modules/{home}>`" if home in with_page else f"     - ``{home}``"]
    out["equations.rst"] = "\n".join(eq) + "\n"
    toc = [".. toctree::", "   :maxdepth: 1", "", "   reference/equations"]
    toc += [f"   reference/{a.slug}" for a in AREAS]
    out["toctree.rst.inc"] = "\n".join(toc) + "\n"
    return out


def write_pages(app=None, config=None) -> None:
    """Write the generated pages (unchanged files are left alone, so Sphinx does not re-read them)."""
    wanted = pages()
    for rel, text in wanted.items():
        path = OUT / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.is_file() or path.read_text() != text:
            path.write_text(text)
    for path in OUT.rglob("*.rst"):
        if str(path.relative_to(OUT)) not in wanted:
            path.unlink()


# ---------------------------------------------------------------------------------------------
# references to shapelib's names, whatever path a docstring uses

def _locate(dotted: str):
    """The object a dotted name reaches (the longest importable module, then attributes), or None."""
    import importlib

    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def resolve_reference(app, env, node, contnode):
    """``missing-reference``: a Python reference to a shapelib name that Sphinx did not find.

    A docstring names a function where it is defined (``shapelib.geometry.gmm.l2_distance``) or,
    inside its module, by its bare name; its page is under the name the API reference documents
    (``shapelib.l2_distance``): that page is the target. A public name of a module that has no
    page of its own (a module constant, a helper the docstring discusses) links to the page of
    the module that defines it, which renders the module's docstring. Anything else stays a
    warning (an error in ``make docs``)."""
    import inspect

    from sphinx.util.nodes import make_refnode

    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    candidates = [target]
    if module:
        candidates += [f"{module}.{cls}.{target}" if cls else None, f"{module}.{target}"]
    page = node["refdoc"].rpartition("/")[2]
    if node["refdoc"].startswith("api/generated/"):  # a docstring: names relative to its object
        obj = _locate(page)
        home = getattr(obj, "__module__", None)
        candidates += [f"{page}.{target}", f"{home}.{target}" if home else None]
    candidates += [f"shapelib.{target}", *_homes_of(target)]
    documented = _documented(env)
    py = env.domains["py"]
    for name in filter(None, candidates):
        if not name.startswith("shapelib"):
            continue
        obj = _locate(name)
        if obj is None:
            continue
        head, _, attr = name.rpartition(".")
        owner = _locate(head)
        qualname = documented.get(id(obj))
        if qualname is None and inspect.isclass(owner) and id(owner) in documented:
            qualname = f"{documented[id(owner)]}.{attr}"  # a method or attribute of a documented class
        if qualname is not None:
            hit = py.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], qualname, node, contnode)
            if hit is not None:
                return hit
        home = getattr(obj, "__module__", None) if callable(obj) and not inspect.ismodule(obj) else None
        home = obj.__name__ if inspect.ismodule(obj) else (home or (head if inspect.ismodule(owner) else None))
        if home and home in _MODULE_PAGES():
            return make_refnode(app.builder, node["refdoc"], f"api/reference/modules/{home}", "", contnode, name)
    if node["refdoc"].startswith("api/generated/"):
        return _class_member(app, env, node, contnode, page, target.rpartition(".")[2])
    return None


def _class_member(app, env, node, contnode, page: str, attr: str):
    """A bare member name in a class's docstring: a method of that class or of a documented
    class of its module (``path_grad_hessian`` of ``AlphaPathMetric`` named in ``PathMetric``'s),
    or a field its Attributes section describes (``mode_shapes``): the member's entry, else the
    class's page."""
    import importlib
    import inspect

    from sphinx.util.nodes import make_refnode

    obj = _locate(page)
    if obj is None:
        return None
    module = obj.__module__ if inspect.isclass(obj) else getattr(obj, "__module__", None)
    classes = [obj] if inspect.isclass(obj) else []
    for e in entries():
        cls = getattr(importlib.import_module(e.module), e.name)
        if inspect.isclass(cls) and cls.__module__ == module and cls is not obj:
            classes.append(cls)
    documented = _documented(env)
    for cls in classes:
        fields = set(getattr(cls, "__dataclass_fields__", {})) | set(getattr(cls, "__annotations__", {}))
        if id(cls) in documented and (hasattr(cls, attr) or attr in fields):
            qualname = documented[id(cls)]
            hit = env.domains["py"].resolve_xref(env, node["refdoc"], app.builder, node["reftype"],
                                                 f"{qualname}.{attr}", node, contnode)
            return hit or make_refnode(app.builder, node["refdoc"], f"api/generated/{qualname}", qualname,
                                       contnode, f"{qualname}.{attr}")
    return None


_DOCUMENTED: dict[int, str] = {}


def _documented(env) -> dict[int, str]:
    """:func:`documented_objects`, once per process (object ids do not outlive it)."""
    if not _DOCUMENTED:
        _DOCUMENTED.update(documented_objects())
    return _DOCUMENTED


_MODULES: list[str] = []


def _MODULE_PAGES() -> set[str]:
    if not _MODULES:
        _MODULES.extend(all_modules())
    return set(_MODULES)


_NAME_HOMES: dict[str, list[str]] = {}


def _homes_of(name: str) -> list[str]:
    """``module.name`` for the one shapelib module that defines a public ``name`` (a bare name in
    a summary line: ``check_pose``, ``TIE_RTOL``), or nothing when none or several do."""
    import importlib
    import re as _re

    if not _NAME_HOMES:
        for modname in all_modules():
            module = importlib.import_module(modname)
            try:
                import inspect

                source = inspect.getsource(module)
            except (OSError, TypeError):
                continue
            for attr in _re.findall(r"^(?:def |class )?([A-Za-z]\w*)\b", source, flags=_re.M):
                if hasattr(module, attr):
                    _NAME_HOMES.setdefault(attr, [])
                    if modname not in _NAME_HOMES[attr]:
                        _NAME_HOMES[attr].append(modname)
    homes = _NAME_HOMES.get(name.rpartition(".")[2] if "." not in name else name, [])
    return [f"{homes[0]}.{name}"] if len(homes) == 1 else []


def module_docstring_directive():
    """``.. module-docstring:: MODULE``: a module's docstring, parsed as numpydoc, without
    declaring the module (for a module whose name a documented function also has:
    ``shapelib.rerank``)."""
    import importlib

    from docutils import nodes
    from docutils.statemachine import StringList
    from numpydoc.docscrape_sphinx import SphinxDocString
    from sphinx.util.docstrings import prepare_docstring
    from sphinx.util.docutils import SphinxDirective

    class ModuleDocstring(SphinxDirective):
        required_arguments = 1

        def run(self):
            doc = importlib.import_module(self.arguments[0]).__doc__ or ""
            # its numpydoc sections (References) as numpydoc renders them on any other page
            doc = str(SphinxDocString(doc, config={}))
            container = nodes.container()
            self.state.nested_parse(StringList(prepare_docstring(doc), source=self.arguments[0]),
                                    self.content_offset, container)
            return container.children

    return ModuleDocstring
