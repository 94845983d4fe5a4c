#!/usr/bin/env bash
# Install illumix into the current Python environment, plus the one system library it wants:
# Debian's libllvm19 for Mitsuba's LLVM backend (LLVM <= 15 crashes it; without any, illumix falls
# back to the much slower scalar_spectral variant). Usage: bash scripts/install.sh [--test] [--blender]
#   --blender: the Cycles backend — Blender's bpy 4.5 in its own Python environment (it pins numpy < 2,
#              illumix needs numpy 2), at $ILLUMIX_BLENDER_VENV (default ~/.cache/illumix/blender-venv);
#              a ~370 MB download. --test implies it (the Cycles tests run in CI).
#   --test:    also Debian's chromium + chromium-driver (root only) for the web explorer's browser tests.
set -euo pipefail
cd "$(dirname "$0")/.."
test_install=0
blender=0
for arg in "$@"; do
  case "$arg" in
    --test) test_install=1; blender=1 ;;
    --blender) blender=1 ;;
    *) echo "install: unknown option $arg (use --test and/or --blender)" >&2; exit 2 ;;
  esac
done
# The renderer (Mitsuba) is the optional extra "render" of the package (a service-only install,
# e.g. docker/Dockerfile.service, leaves it out); this script always installs it.
extras="render"
# Tests also exercise the Ray executor against a local Ray instance, and a 3-node Ray cluster rendering
# into an S3 server ("cluster": s3fs + moto's server); "bench" adds the benchmarks' plots.
[ "$test_install" = 1 ] && extras="render,ray,test,bench,export,evaluate,cluster"
# "blender": what the main environment needs to read Cycles' multilayer EXRs (OpenEXR).
[ "$blender" = 1 ] && extras="${extras},blender"
# Debian's libllvm19 puts libLLVM-19.so under /usr/lib/<triplet>/, LLVM's own packages under /usr/lib/llvm-N/.
# (a loop: `ls` of several patterns fails when any one of them matches nothing)
have_llvm=0
for f in /usr/lib/llvm-1[6-9]/lib/libLLVM*.so* /usr/lib/llvm-2*/lib/libLLVM*.so* \
         /usr/lib/*-linux-gnu/libLLVM-1[6-9]*.so* /usr/lib/*-linux-gnu/libLLVM-2*.so* \
         /usr/lib/*-linux-gnu/libLLVM.so.1[6-9]* /usr/lib/*-linux-gnu/libLLVM.so.2*; do
  [ -e "$f" ] && have_llvm=1 && break
done
if [ "$have_llvm" = 0 ]; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "install: adding libllvm19 (Mitsuba LLVM backend)" >&2
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19) >&2 \
      || echo "install: could not install libllvm19; rendering will use scalar_spectral" >&2
  else
    echo "install: no libLLVM >= 16 found and cannot apt-get it (not root / not Debian);" \
         "rendering will use scalar_spectral. On Debian: apt-get install libllvm19" >&2
  fi
fi
python3 -m pip install -q -e ".[${extras}]"
# Automatic ColorChecker detection for `sensors estimate --chart-photo`: without its dependencies,
# which would add opencv-python beside our opencv-contrib (two packages writing one cv2) and
# OpenImageIO (only used to read files by path; illumix hands it arrays).
python3 -m pip install -q --no-deps "colour-checker-detection>=0.2.3,<0.3"
# The Python client is its own package (numpy + httpx only); install it beside the server.
python3 -m pip install -q -e clients/python
if [ "$blender" = 1 ]; then
  venv="${ILLUMIX_BLENDER_VENV:-$HOME/.cache/illumix/blender-venv}"
  if ! "$venv/bin/python" -c "import bpy" >/dev/null 2>&1; then
    echo "install: Blender (bpy 4.5) into $venv for the cycles backend" >&2
    { python3 -m venv "$venv" && "$venv/bin/python" -m pip install -q "bpy>=4.5,<4.6"; } \
      || echo "install: could not install bpy; --backend cycles and its tests will be unavailable" >&2
  fi
fi
if [ "$test_install" = 1 ]; then
  # The web explorer's browser tests (tests/test_web.py) drive Debian's headless Chromium with
  # Selenium; without it they skip with a reason.
  if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then
    true  # already there
  elif command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "install: adding chromium + chromium-driver (the web explorer's browser tests)" >&2
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver) >&2 \
      || echo "install: could not install chromium; the browser tests will skip" >&2
  else
    echo "install: no chromium/chromedriver and cannot apt-get them (not root / not Debian);" \
         "the browser tests will skip. On Debian: apt-get install chromium chromium-driver" >&2
  fi
  # The client's PyTorch dataset tests want torch. Pin the CPU build so pip takes the local CPU
  # wheel and never pulls the multi-GB CUDA one; without it those tests skip with a reason.
  python3 -m pip install -q "torch==2.13.0+cpu" \
    || echo "install: torch==2.13.0+cpu not available; the client's torch tests will skip" >&2
fi
