#!/usr/bin/env bash
# CI: the package a user installs. Builds the wheel and the sdist (`python -m build`), installs the
# wheel into a clean virtual environment in a temporary folder outside the source tree, and from
# that folder runs the README's Python example, one statistic (tangent PCA of the corpus callosum),
# one registration (`sl.register`) and `shapelib --help`. The data come from SHAPELIB_DATA_DIR (no
# download); pip reaches the package index for the dependencies only when the wheelhouse
# (SHAPELIB_WHEELHOUSE, default ~/.cache/shapelib/wheelhouse) lacks some.
#
#   .ci/wheel_check.sh            (from anywhere; PYTHON picks the interpreter, python3 by default)
set -euo pipefail
cd "$(dirname "$0")/.."
SRC="$(pwd)"
PYTHON="${PYTHON:-python3}"
export SHAPELIB_DATA_DIR="${SHAPELIB_DATA_DIR:-$(cd .. && pwd)/shared/data}"
[ -d "$SHAPELIB_DATA_DIR" ] || { echo "wheel_check: SHAPELIB_DATA_DIR=$SHAPELIB_DATA_DIR is not a folder" >&2; exit 1; }
start=$(date +%s)
stage() { echo "== [$(( $(date +%s) - start )) s] $*"; }
quiet() {  # run a command, its output shown only when it fails
    "$@" > "$WORK/cmd.log" 2>&1 || { cat "$WORK/cmd.log"; return 1; }
}
WORK="$(mktemp -d "${TMPDIR:-/tmp}/shapelib-wheel-check.XXXXXX")"
trap 'rm -rf "$WORK"' EXIT
case "$WORK" in "$SRC"/*) echo "wheel_check: $WORK is inside the source tree" >&2; exit 1;; esac

stage "build the wheel and the sdist"
# `build` from the calling environment when it has it (the dev extra), else from a throwaway venv
if "$PYTHON" -m build --version > /dev/null 2>&1; then BUILD_PY="$PYTHON"; else
    "$PYTHON" -m venv "$WORK/build-env"
    quiet "$WORK/build-env/bin/python" -m pip install "build>=1.0"
    BUILD_PY="$WORK/build-env/bin/python"
fi
quiet "$BUILD_PY" -m build --outdir "$WORK/dist" "$SRC"
ls "$WORK/dist"
wheel=$(ls "$WORK"/dist/shapelib-*.whl)
ls "$WORK"/dist/shapelib-*.tar.gz > /dev/null

stage "install the wheel into a clean venv"
"$PYTHON" -m venv "$WORK/venv"
# the dependencies' wheels are kept in a wheelhouse between runs: offline from the second run on
WHEELHOUSE="${SHAPELIB_WHEELHOUSE:-${XDG_CACHE_HOME:-$HOME/.cache}/shapelib/wheelhouse}"
mkdir -p "$WHEELHOUSE"
if ! "$WORK/venv/bin/python" -m pip install --no-compile --no-index --find-links "$WHEELHOUSE" "$wheel" > "$WORK/cmd.log" 2>&1; then
    echo "(the wheelhouse $WHEELHOUSE lacks some dependencies: downloading them from the package index)"
    quiet "$WORK/venv/bin/python" -m pip download --dest "$WHEELHOUSE" "$wheel"
    rm -f "$WHEELHOUSE"/shapelib-*
    quiet "$WORK/venv/bin/python" -m pip install --no-compile --no-index --find-links "$WHEELHOUSE" "$wheel"
fi

# from a folder outside the source tree, with nothing of it on the path
mkdir "$WORK/run" && cd "$WORK/run"
unset PYTHONPATH
PY="$WORK/venv/bin/python"
"$PY" - <<'EOF'
import shapelib
from shapelib.datasets import REGISTRY_PATH
print("shapelib", shapelib.__version__, "from", shapelib.__file__)
assert "site-packages" in shapelib.__file__, shapelib.__file__
assert REGISTRY_PATH.is_file(), REGISTRY_PATH
EOF

stage "the README's Python example"
"$PY" - "$SRC/README.md" > readme_example.py <<'EOF'
import re, sys
text = open(sys.argv[1], encoding="utf-8").read()
section = text.split("\n## Example\n", 1)[1]
print(re.search(r"```python\n(.*?)```", section, re.S).group(1))
EOF
"$PY" readme_example.py

stage "one statistic: tangent PCA of the corpus callosum"
"$PY" - <<'EOF'
import numpy as np
import shapelib as sl
from shapelib.datasets import load_corpus_callosum

x = sl.to_centroid_size(load_corpus_callosum()[0])
pca = sl.tangent_pca(x, metric="alpha", sigma2=0.5, n_jobs=1)
print("explained variance ratio", pca.explained_variance_ratio[:3].round(3))
assert pca.mean.shape == (63, 2) and np.allclose(pca.scores.mean(axis=0), 0, atol=1e-6)
EOF

stage "one registration: sl.register"
"$PY" - <<'EOF'
import numpy as np
import shapelib as sl

t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
source = np.c_[np.cos(t), 0.6 * np.sin(t)]
c, s = np.cos(0.5), np.sin(0.5)
target = source @ np.array([[c, -s], [s, c]]).T + [0.3, -0.2]
r = sl.register(source, target)
err = np.linalg.norm(r.points[:, None] - target[None], axis=-1).min(axis=1).max()
print("registered 30 points: the farthest lies", f"{err:.1e}", "from the target")
assert r.converged and err < 1e-3
EOF

stage "shapelib --help"
"$WORK/venv/bin/shapelib" --help

echo "wheel_check: passed in $(( $(date +%s) - start )) s"
