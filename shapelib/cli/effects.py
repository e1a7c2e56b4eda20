"""``shapelib test`` and ``shapelib regress``: does shape differ between groups, does it change
with a covariate — permutation tests on the distance matrix of any metric (PERMANOVA, McArdle &
Anderson 2001), with covariates read from a CSV file by specimen id."""

from __future__ import annotations

import warnings

import numpy as np

from ._common import (CLIError, _align_pose, _auto_sigma2, _check_jobs, _file_options, _metric_options, _metric_params,
                      _output_path, _read, _write_frame)

EXAMPLES = {
    "test": ("example:\n  shapelib test aligned.tps --covariates specimens.csv --by species \\\n"
             "      --metric procrustes --permutations 999 -o test.csv"),
    "regress": ("example:\n  shapelib regress aligned.tps --covariates specimens.csv --by age \\\n"
                "      --metric alpha_bound --sigma2 auto -o regress.csv"),
}


def _covariates(path, spec, column, id_column):
    """The ``column`` of CSV ``path``, one value per specimen of the landmark file, matched by id."""
    import pandas as pd

    try:
        table = pd.read_csv(path, dtype={id_column: str} if id_column else None)
    except (OSError, ValueError) as exc:
        raise CLIError(f"--covariates {path}: {exc}") from None
    idc = id_column or table.columns[0]
    for c in (idc, column):
        if c not in table.columns:
            raise CLIError(f"--covariates {path}: no column {c!r}; columns: {', '.join(map(str, table.columns))}")
    keys = table[idc].astype(str).str.strip()
    if keys.duplicated().any():
        raise CLIError(f"--covariates {path}: id {keys[keys.duplicated()].iloc[0]!r} occurs more than once")
    values = dict(zip(keys, table[column]))
    ids = spec["id"].astype(str).tolist()
    absent = [i for i in ids if i not in values]
    if absent:
        raise CLIError(f"--covariates {path}: no row for specimen(s) {', '.join(absent[:5])}"
                       f"{', …' if len(absent) > 5 else ''} of the landmark file (ids matched on column {idc!r})")
    out = pd.Series([values[i] for i in ids], index=ids, name=column)
    if out.isna().any():
        raise CLIError(f"--covariates {path}: {column} is empty for specimen(s) "
                       f"{', '.join(out.index[out.isna()][:5])}")
    return out


def _distances(args, shapes):
    from ..pairwise import pairwise_distances

    params = _metric_params(args)
    params = _auto_sigma2(args, params, shapes)
    shapes = _align_pose(args, shapes, params)
    return pairwise_distances(shapes, metric=args.metric, n_jobs=args.jobs, progress=False, **params)


def _check(args):
    if args.permutations < 19:
        raise CLIError(f"--permutations must be at least 19; got {args.permutations}")
    _check_jobs(args)


def cmd_test(args) -> int:
    import pandas as pd

    from ..statistics.distance_based import permanova
    from ..statistics.multiple import holm_adjust

    _check(args)
    out = _output_path(args.output, suffixes=(".csv",), option="-o") if args.output else None
    shapes, spec = _read(args)
    groups = _covariates(args.covariates, spec, args.by, args.id_column).astype(str).to_numpy()
    levels, sizes = np.unique(groups, return_counts=True)
    if len(levels) < 2:
        raise CLIError(f"--by {args.by}: one group ({levels[0]!r}); a test needs two or more")
    if sizes.min() < 3:
        warnings.warn(f"--by {args.by}: group {levels[sizes.argmin()]!r} has {sizes.min()} specimen(s): its mean is "
                      "barely estimated and its permutations are few")
    d = _distances(args, shapes)
    res = permanova(d, {args.by: groups}, n_permutations=args.permutations, seed=args.seed)
    row = res.table.loc[args.by]
    rows = [{"comparison": "all groups", "n": len(groups), "df": int(row["df"]), "pseudo_F": row["pseudo_F"],
             "r2": row["r2"], "p_value": row["p_value"], "p_holm": np.nan}]
    print(f"{args.metric}: {len(levels)} groups of {args.by} ({', '.join(f'{g} n = {n}' for g, n in zip(levels, sizes))})"
          f": pseudo-F = {row['pseudo_F']:.4g}, R² = {row['r2']:.3g}, permutation p = {row['p_value']:.4g} "
          f"({args.permutations} permutations)")
    if len(levels) > 2:
        pairs = [(a, b) for k, a in enumerate(levels) for b in levels[k + 1:]]
        post = []
        for a, b in pairs:
            sel = np.isin(groups, [a, b])
            r = permanova(d[np.ix_(sel, sel)], {args.by: groups[sel]}, n_permutations=args.permutations,
                          seed=args.seed).table.loc[args.by]
            post.append({"comparison": f"{a} vs {b}", "n": int(sel.sum()), "df": int(r["df"]),
                         "pseudo_F": r["pseudo_F"], "r2": r["r2"], "p_value": r["p_value"]})
        for rec, ph in zip(post, holm_adjust([p["p_value"] for p in post])):
            rec["p_holm"] = ph
        rows += post
        print(f"pairwise (Holm-adjusted over {len(pairs)} comparisons):")
        for rec in post:
            print(f"  {rec['comparison']:<24} pseudo-F = {rec['pseudo_F']:<9.4g} p = {rec['p_value']:<7.4g} "
                  f"Holm p = {rec['p_holm']:.4g}")
    if out is not None:
        _write_frame(pd.DataFrame(rows), out, index=False)
        print(f"table -> {out}")
    return 0


def cmd_regress(args) -> int:
    import pandas as pd

    from ..statistics.distance_based import permanova

    _check(args)
    out = _output_path(args.output, suffixes=(".csv",), option="-o") if args.output else None
    shapes, spec = _read(args)
    raw = _covariates(args.covariates, spec, args.by, args.id_column)
    x = pd.to_numeric(raw, errors="coerce")
    if x.isna().any():
        bad = raw[x.isna()]
        raise CLIError(f"--by {args.by}: not a number for specimen {bad.index[0]!r} ({bad.iloc[0]!r}); regress takes "
                       "a numeric covariate (shapelib test compares groups)")
    if args.log:
        if (x <= 0).any():
            raise CLIError(f"--log: {args.by} must be positive; specimen {x.index[(x <= 0).to_numpy()][0]!r} has "
                           f"{x[x <= 0].iloc[0]}")
        x = np.log(x)
    if np.ptp(x.to_numpy()) == 0:
        raise CLIError(f"--by {args.by}: the same value for every specimen; nothing to regress on")
    d = _distances(args, shapes)
    res = permanova(d, {args.by: x.to_numpy(dtype=np.float64)}, n_permutations=args.permutations, seed=args.seed)
    row = res.table.loc[args.by]
    name = f"log {args.by}" if args.log else args.by
    print(f"{args.metric}: shape on {name} ({len(x)} specimens): R² = {row['r2']:.4g} of the shape variation, "
          f"pseudo-F = {row['pseudo_F']:.4g}, permutation p = {row['p_value']:.4g} ({args.permutations} permutations)")
    if out is not None:
        _write_frame(res.table.drop(columns=["p_tests"]).reset_index(), out, index=False)
        print(f"table -> {out}")
    return 0


def _options(p, *, covariate_help):
    from ..distances import METRICS

    _file_options(p)
    g = p.add_argument_group("covariates")
    g.add_argument("--covariates", required=True, metavar="C.csv",
                   help="CSV file with one row per specimen: an id column and the covariate columns")
    g.add_argument("--by", required=True, metavar="COLUMN", help=covariate_help)
    g.add_argument("--id-column", metavar="NAME", help="the column of C.csv holding the specimen ids as in FILE "
                   "(default: its first column)")
    _metric_options(p, metrics=METRICS)
    p.add_argument("--permutations", type=int, default=999, metavar="P", help="random permutations (default 999)")
    p.add_argument("--seed", type=int, default=0, help="seed of the permutations (default 0)")
    p.add_argument("--jobs", type=int, metavar="N", help="worker processes for the distance matrix")
    p.add_argument("-o", "--output", metavar="T.csv", help="write the table")


def register(add) -> None:
    """Add ``test`` and ``regress`` to the parser (``add(name, help, epilog)`` returns the subparser)."""
    p = add("test", "do groups differ in shape? PERMANOVA on the distance matrix, pairwise Holm-adjusted post hoc",
            EXAMPLES["test"])
    _options(p, covariate_help="the column of C.csv holding each specimen's group (two or more groups)")
    p.set_defaults(func=cmd_test)
    p = add("regress", "does shape change with a covariate? distance-based regression with a permutation p",
            EXAMPLES["regress"])
    _options(p, covariate_help="the numeric column of C.csv to regress shape on (e.g. age, centroid size)")
    p.add_argument("--log", action="store_true", help="regress on the logarithm of the covariate (e.g. log size)")
    p.set_defaults(func=cmd_regress)

