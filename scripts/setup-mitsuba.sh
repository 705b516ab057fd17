#!/usr/bin/env bash
# Installs Mitsuba 3 into .venv-mitsuba/ at the repository root, for the `mitsuba_compare`
# experiment and its test (reference::mitsuba finds the venv there, or via $SCATTERBENCH_MITSUBA_PYTHON).
#
# Idempotent: an existing venv that already imports mitsuba is kept. Prints the version.
#
#   scripts/setup-mitsuba.sh            # scalar_rgb variant (works everywhere)
#
# The llvm_ad_rgb variant additionally needs a newer LLVM at run time than Debian 12's default
# LLVM 15 (with which Dr.Jit aborts): `apt-get install -y libllvm19`, after which Dr.Jit finds
# it by itself (or set DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so). The
# script reports whether llvm_ad_rgb works; scalar_rgb needs nothing else.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv-mitsuba
PYTHON=${PYTHON:-python3}
SPEC=${MITSUBA_SPEC:-mitsuba==3.*}

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c 'import mitsuba' >/dev/null 2>&1; then
  echo "== $VENV already has mitsuba"
else
  echo "== creating $VENV with $($PYTHON --version 2>&1)"
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  "$VENV/bin/python" -m pip install --quiet "$SPEC"
fi

"$VENV/bin/python" - <<'PY'
import mitsuba as mi
mi.set_variant("scalar_rgb")
print(f"mitsuba {mi.__version__} (variants: {', '.join(mi.variants())})")
PY

# A crash of Dr.Jit's LLVM back end must not fail the setup: probe it in a child process.
if "$VENV/bin/python" -c 'import mitsuba as mi; mi.set_variant("llvm_ad_rgb"); mi.render(mi.load_dict(mi.cornell_box()), spp=1)' >/dev/null 2>&1; then
  echo "llvm_ad_rgb: works"
else
  echo "llvm_ad_rgb: unusable here (install libllvm19: apt-get install -y libllvm19); scalar_rgb is unaffected"
fi
