#!/usr/bin/env bash
# Create .venv if missing, install pinned dependencies, build hexapod_interfaces (rosidl) into
# the venv, install the five Python packages. Skips everything in about a second when the
# inputs (requirements, lock, .msg files, package manifests) have not changed.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
PY=${PYTHON:-python3}
PKGS="hexapod_common hexapod_gait hexapod_bench_drivers hexapod_energy slip_identification"

stamp_of() {
  cat requirements.txt requirements.lock src/hexapod_interfaces/CMakeLists.txt \
      src/hexapod_interfaces/package.xml src/hexapod_interfaces/msg/*.msg \
      $(for p in $PKGS; do echo "$p/setup.py $p/package.xml"; done) scripts/setup.sh \
    | sha256sum | cut -d' ' -f1
}
want=$(stamp_of)
if [ -f "$VENV/.setup-stamp" ] && [ "$(cat "$VENV/.setup-stamp")" = "$want" ]; then
  exit 0
fi

for tool in cmake cc; do
  command -v "$tool" >/dev/null || { echo "setup: '$tool' is required (cmake and a C compiler)" >&2; exit 1; }
done
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
. "$VENV/bin/activate"
echo "setup: installing pinned dependencies into $VENV" >&2
# uv installs the ~220 pinned wheels in parallel (about 10 s against pip's 70 s); pip is the
# fallback when uv cannot be installed or fails (same requirements, same lock).
UV_VERSION=0.13.8
if python -m pip install -q --disable-pip-version-check "uv==$UV_VERSION" >/dev/null 2>&1 \
   && "$VENV/bin/uv" pip install -q --python "$VENV/bin/python" -r requirements.txt -c requirements.lock; then
  :
else
  echo "setup: uv unavailable or failed; installing with pip" >&2
  python -m pip install -q --disable-pip-version-check -r requirements.txt -c requirements.lock
fi

echo "setup: building hexapod_interfaces (rosidl)" >&2
export CMAKE_PREFIX_PATH=$VENV AMENT_PREFIX_PATH=$VENV
BUILD=$ROOT/build/hexapod_interfaces
rm -rf "$BUILD"
mkdir -p "$ROOT/build"
cmake -S src/hexapod_interfaces -B "$BUILD" -DCMAKE_INSTALL_PREFIX="$VENV" \
  -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" >"$ROOT/build/interfaces.log" 2>&1 \
  && cmake --build "$BUILD" -j2 >>"$ROOT/build/interfaces.log" 2>&1 \
  && cmake --install "$BUILD" >>"$ROOT/build/interfaces.log" 2>&1 \
  || { echo "setup: interface build failed; see build/interfaces.log" >&2; tail -30 "$ROOT/build/interfaces.log" >&2; exit 1; }
(cd /tmp && python -c 'import hexapod_interfaces.msg') \
  || { echo "setup: hexapod_interfaces does not import after the build" >&2; exit 1; }

echo "setup: installing the project's packages (editable)" >&2
args=()
for p in $PKGS; do args+=(-e "./$p"); done
python -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation "${args[@]}" 2>&1 \
  | grep -vE "BuildBackendWarning|Please be careful|name as your package|warnings.warn|^ *$" || true
# setup.cfg's [develop] script_dir puts the executables in .venv/lib/<pkg>/ (the ros2 run
# layout) when setuptools honours it; make them callable from .venv/bin as well.
for p in $PKGS; do
  for exe in "$VENV/lib/$p"/*; do
    [ -f "$exe" ] && [ -x "$exe" ] || continue
    [ -e "$VENV/bin/$(basename "$exe")" ] || ln -s "$exe" "$VENV/bin/$(basename "$exe")"
  done
done
# Bytecode for every installed module and the project's packages: uv installs without it, and
# with PYTHONDONTWRITEBYTECODE set (as on these machines, and in test.sh) every process would
# otherwise compile scipy & co. from source at import (the 50 x 50 power map's first call
# 1.15 s -> 0.5 s, `hexapod-analyze --help` and each test process faster alike).
echo "setup: compiling bytecode" >&2
PYTHONDONTWRITEBYTECODE= python -m compileall -q -j 0 \
  "$(python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" \
  $(for p in $PKGS; do echo "$ROOT/$p/$p"; done) >/dev/null 2>&1 || true
for exe in bag_replay bag_recorder hexapod-demo hexapod-analyze hexapod-sim energy_monitor; do
  [ -x "$VENV/bin/$exe" ] || { echo "setup: $exe was not installed" >&2; exit 1; }
done
echo "$want" > "$VENV/.setup-stamp"
echo "setup: done" >&2
