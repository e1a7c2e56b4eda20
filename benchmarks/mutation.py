"""Mutation testing of the numerical core with mutmut: how many small changes to a module (an operator,
a constant, an argument) its tests notice.

    python benchmarks/mutation.py shapelib/geometry/gmm.py [more modules]   # or: make mutate MODULE=...
    python benchmarks/mutation.py --since <commit>                          # or: make mutate SINCE=...
    python benchmarks/mutation.py --renote          # the record's survivors' reasons again from the notes
    python benchmarks/mutation.py MODULE --only f g # the mutants of functions f and g only (Class.method for a method)

Each module is mutated in a scratch copy of the repository (build/mutation/<module>/, so the checkout
is never touched) and only the test files that cover it are run against each mutant (the mapping is
benchmarks/mutation_targets.toml; slow-marked tests are left out, as in ``make test``). A mutant that
runs past mutmut's time limit (``--timeout-multiplier`` times the tests' own time) counts as killed.

The score of each module, with the date, the machine, mutmut's version and every surviving mutant
(its diff, and why it survives: benchmarks/mutation_notes.toml, written by hand), goes into
docs/_data/benchmarks/mutation.json (``--record``), which the performance page renders.
"""

from __future__ import annotations

import argparse
import fnmatch
import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks._machine import RECORD_DIR, loadavg, machine  # noqa: E402

TARGETS = ROOT / "benchmarks" / "mutation_targets.toml"
NOTES = ROOT / "benchmarks" / "mutation_notes.toml"
SCRATCH = ROOT / "build" / "mutation"
RECORD = RECORD_DIR / "mutation.json"
#: the numerical core: what `--since` looks at
CORE = ("shapelib/geometry/", "shapelib/solver/", "shapelib/pointsets/", "shapelib/statistics/",
        "shapelib/comparison/", "shapelib/retrieval.py", "shapelib/rerank.py")
KILLED = {"killed", "timeout"}


def targets() -> dict[str, list[str]]:
    """Module -> the test files that cover it (benchmarks/mutation_targets.toml)."""
    return tomllib.loads(TARGETS.read_text())["modules"]


def fork_unsafe() -> set[str]:
    """Modules whose covering tests run JAX (``[fork_unsafe]`` of benchmarks/mutation_targets.toml)."""
    return set(tomllib.loads(TARGETS.read_text()).get("fork_unsafe", {}).get("modules", []))


def notes() -> dict[str, str]:
    """Mutant name -> why it survives (benchmarks/mutation_notes.toml), where someone has looked."""
    return tomllib.loads(NOTES.read_text()).get("survivors", {}) if NOTES.is_file() else {}


def reason(why: dict[str, str], name: str) -> str:
    """The note for mutant ``name``: its own, else the first glob key that matches it (a note for every
    mutant of a function no test reaches, ``shapelib.x.x_f__mutmut_*``), else "not yet looked at"."""
    if name in why:
        return why[name]
    return next((text for key, text in why.items() if "*" in key and fnmatch.fnmatchcase(name, key)),
                "not yet looked at")


def changed_since(commit: str) -> list[str]:
    """The modules of the numerical core changed since ``commit`` (committed or not)."""
    out = subprocess.run(["git", "diff", "--name-only", commit, "--", "shapelib"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout.split()
    return sorted(p for p in out if p.endswith(".py") and p.startswith(CORE) and (ROOT / p).is_file())


def _mutmut_config(module: str, tests: list[str], timeout_multiplier: float, forkserver: bool = False) -> str:
    """mutmut's settings. ``forkserver``: each mutant's tests run in a process forked from a server that
    has only collected the tests, never run one: JAX is multithreaded once its backend has started (a
    test ran), and a process forked from it after that hangs, which mutmut would count as killed."""
    quoted = lambda xs: "[" + ", ".join(json.dumps(x) for x in xs) + "]"  # noqa: E731
    isolation = 'process_isolation = "forkserver"\nforkserver_warmup = "collect"\n' if forkserver else ""
    return ("\n[tool.mutmut]\n" + isolation +
            'source_paths = ["shapelib"]\n'
            f"only_mutate = {quoted([module])}\n"
            f"pytest_add_cli_args_test_selection = {quoted(tests)}\n"
            'pytest_add_cli_args = ["-p", "no:xdist", "-p", "no:cacheprovider", "-q", "--durations=0"]\n'
            'also_copy = ["data"]\n'
            f"timeout_multiplier = {float(timeout_multiplier)}\n"
            "timeout_constant = 5.0\n")


def _mutmut(args: list[str], cwd: Path, log=None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.setdefault("SHAPELIB_DATA_DIR", str(ROOT.parent / "shared" / "data"))
    # each mutant's process compiles its JAX programs afresh; they do not change between mutants of
    # code outside the kernels, so the persistent cache turns a compilation into a file read
    env.setdefault("JAX_COMPILATION_CACHE_DIR", str(cwd / "jax-cache"))
    env.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    return subprocess.run([sys.executable, "-m", "mutmut", *args], cwd=cwd, env=env, text=True,
                          stdout=log if log is not None else subprocess.PIPE,
                          stderr=subprocess.STDOUT if log is not None else subprocess.PIPE)


_DIFFS = """
import json, sys
from mutmut.mutation.diff_apply import find_mutant, get_diff_for_mutant
names = json.load(sys.stdin)
path = find_mutant(names[0]).path if names else None
print(json.dumps({n: get_diff_for_mutant(n, path=path) for n in names}))
"""


def _diffs(names: list[str], work: Path) -> dict[str, str]:
    """The diff of each mutant, from one process (``mutmut show`` per mutant starts one each)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", _DIFFS], cwd=work, env=env, input=json.dumps(names), text=True,
                         capture_output=True, check=True).stdout
    return json.loads(out)


def mutant_patterns(slug: str, functions: list[str]) -> list[str]:
    """mutmut's names of the mutants of ``functions`` of module ``slug`` (``f``, or ``Class.method``), as globs."""
    return [f"{slug}.x{'ǁ'.join(['', *f.split('.')]) if '.' in f else '_' + f}__mutmut_*" for f in functions]


def run_module(module: str, tests: list[str], *, max_children: int, timeout_multiplier: float,
               only: list[str] | None = None) -> dict:
    """Mutate ``module`` in a scratch copy, run ``tests`` against every mutant (or those of the functions
    ``only``); the counts and the survivors."""
    slug = module.removesuffix(".py").replace("/", ".")
    patterns = mutant_patterns(slug, only) if only else []
    work = SCRATCH / slug
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    skip = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
    for folder in ("shapelib", "tests", "data"):
        shutil.copytree(ROOT / folder, work / folder, ignore=skip)
    (work / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text()
                                         + _mutmut_config(module, tests, timeout_multiplier, module in fork_unsafe()))
    load_start, t0 = loadavg(), time.perf_counter()
    with open(work / "mutmut.log", "w") as log:
        # mutmut picks the tests of a glob by the functions' names it matches: a glob of the function's name
        # (the exact mutants are picked from the results below)
        wide = [q.removesuffix("__mutmut_*") + "*" for q in patterns]
        rc = _mutmut(["run", "--max-children", str(max_children), *wide], work, log).returncode
    seconds = time.perf_counter() - t0
    listing = _mutmut(["results", "--all", "true"], work).stdout
    status = dict(re.findall(r"^\s+(\S+): (.+?)\s*$", listing, flags=re.M))
    if patterns:
        status = {k: v for k, v in status.items() if any(fnmatch.fnmatchcase(k, p) for p in patterns)}
    if rc != 0 or not status:
        tail = (work / "mutmut.log").read_text()[-3000:]
        raise RuntimeError(f"mutmut failed on {module} (exit {rc}); the end of {work / 'mutmut.log'}:\n{tail}")
    why = notes()
    counts: dict[str, int] = {}
    for s in status.values():
        counts[s] = counts.get(s, 0) + 1
    survivors = []
    left = sorted(name for name, s in status.items() if s not in KILLED)
    diffs = _diffs(left, work)
    for name in left:
        body = "\n".join(line for line in diffs[name].splitlines()
                         if line.startswith(("+", "-")) and not line.startswith(("+++", "---")))
        survivors.append({"mutant": name, "status": status[name], "diff": body,
                          "why": reason(why, name)})
    killed = sum(counts.get(s, 0) for s in KILLED)
    run = {"module": module, "tests": tests, "date": machine()["date"], "tool": f"mutmut {_version()}",
            "loadavg_start": load_start, "loadavg_end": loadavg(), "seconds": round(seconds, 1),
            "timeout_multiplier": timeout_multiplier, "mutants": len(status), "killed": killed,
            "survived": len(status) - killed, "by_status": counts,
            "score": round(100.0 * killed / len(status), 1), "survivors": survivors}
    if only:  # a part of the module: the record says which
        run["only"] = list(only)
    return run


def _version() -> str:
    return importlib.metadata.version("mutmut")


def write_record(runs: list[dict], argv: list[str]) -> Path:
    """Merge ``runs`` into docs/_data/benchmarks/mutation.json: one entry per module, the latest run each."""
    old = json.loads(RECORD.read_text()) if RECORD.is_file() else {}
    modules = {m["module"]: m for m in old.get("results", {}).get("modules", [])}
    modules.update({r["module"]: r for r in runs})
    data = {"benchmark": "mutation", "command": " ".join(["python benchmarks/mutation.py", *(a for a in argv if a != "--record")]),
            "machine": machine(),
            "results": {"tool": f"mutmut {_version()}", "modules": sorted(modules.values(), key=lambda m: m["module"])}}
    RECORD.parent.mkdir(parents=True, exist_ok=True)
    RECORD.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    return RECORD


def renote() -> Path:
    """Rewrite the reasons of the recorded survivors from benchmarks/mutation_notes.toml (no mutants run)."""
    data = json.loads(RECORD.read_text())
    why = notes()
    for m in data["results"]["modules"]:
        for s in m["survivors"]:
            s["why"] = reason(why, s["mutant"])
    RECORD.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    return RECORD


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("modules", nargs="*", help="modules to mutate, e.g. shapelib/geometry/gmm.py")
    p.add_argument("--since", metavar="COMMIT", help="mutate the modules of the numerical core changed since COMMIT")
    p.add_argument("--max-children", type=int, default=max(1, (os.cpu_count() or 2) - 1),
                   help="mutants tested at once (default: the cores but one)")
    p.add_argument("--timeout-multiplier", type=float, default=10.0,
                   help="a mutant whose tests run this many times longer than unmutated is killed (timeout)")
    p.add_argument("--only", nargs="+", metavar="FUNCTION",
                   help="mutate only these functions of the (one) module (Class.method for a method); the record "
                        "names them")
    p.add_argument("--record", action="store_true", help="write the scores into docs/_data/benchmarks/mutation.json")
    p.add_argument("--renote", action="store_true",
                   help="only rewrite the recorded survivors' reasons from benchmarks/mutation_notes.toml")
    a = p.parse_args(argv)
    if a.renote:
        print(f"reasons rewritten in {renote()}")
        return 0
    known = targets()
    modules = list(a.modules)
    if a.since:
        changed = changed_since(a.since)
        unmapped = [m for m in changed if m not in known]
        if unmapped:
            print("changed but not in benchmarks/mutation_targets.toml (not mutated): " + ", ".join(unmapped))
        modules += [m for m in changed if m in known and m not in modules]
    if not modules:
        p.error("name a module (e.g. shapelib/geometry/gmm.py) or --since COMMIT with changed, mapped modules")
    for m in modules:
        if m not in known:
            raise SystemExit(f"{m} is not in benchmarks/mutation_targets.toml: add it with the tests that cover it; "
                             f"known: {', '.join(sorted(known))}")
    if a.only and len(modules) != 1:
        p.error("--only needs exactly one module")
    runs = []
    for m in modules:
        print(f"mutating {m} (tests: {' '.join(known[m])}) in {SCRATCH}", flush=True)
        r = run_module(m, known[m], max_children=a.max_children, timeout_multiplier=a.timeout_multiplier, only=a.only)
        runs.append(r)
        part = f" ({', '.join(a.only)} only)" if a.only else ""
        print(f"{m}{part}: {r['mutants']} mutants, {r['killed']} killed, {r['survived']} survived "
              f"({r['score']:.1f} %) in {r['seconds']:.0f} s", flush=True)
        for s in r["survivors"]:
            print(f"  {s['mutant']} [{s['status']}] {s['why']}\n    " + s["diff"].replace("\n", "\n    "))
    if a.record:
        print(f"recorded in {write_record(runs, argv)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
