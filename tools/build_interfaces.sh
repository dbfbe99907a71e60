#!/usr/bin/env bash
# Generate and install the interface packages under interfaces/ (control_msgs) into a venv.
#
#   tools/build_interfaces.sh [VENV]      (default .venv; `make setup` runs it)
#
# control_msgs has no PyPI wheel. The venv's rosidl generators (requirements-build.txt), CMake
# and the machine's C/C++ compiler build its C and Python type support; it is installed into
# the venv prefix, where the wheels' bootstrap already puts <venv>/lib on the library path.
# A stamp in the venv holds a hash of the definitions, this script and the pins (the generators'
# and the message packages' versions): unchanged inputs are not rebuilt.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$(cd "${1:-$ROOT/.venv}" 2>/dev/null && pwd)" || {
  echo "build_interfaces: no venv at '${1:-$ROOT/.venv}' (run make setup)" >&2; exit 2; }
PY="$VENV/bin/python"
PACKAGES=(control_msgs)
STAMP="$VENV/.pdsmc-interfaces"
BUILD="$ROOT/build/interfaces"

fail() { echo "build_interfaces: $*" >&2; exit 1; }

[ -x "$PY" ] || fail "no Python at $PY (run make setup)"
# what the build depends on: every file of the packages, this script, the pins of the generators
# and of the message packages the definitions use (constraints.txt)
hash_inputs() {
  (cd "$ROOT" && find "${PACKAGES[@]/#/interfaces/}" -type f -print0 | sort -z | xargs -0 sha256sum
   sha256sum tools/build_interfaces.sh requirements-build.txt constraints.txt) | sha256sum | cut -d' ' -f1
}
WANT="$(hash_inputs)"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ]; then
  for pkg in "${PACKAGES[@]}"; do
    [ -f "$VENV/share/ament_index/resource_index/packages/$pkg" ] || { WANT_REBUILD=1; break; }
  done
  if [ -z "${WANT_REBUILD:-}" ]; then
    touch "$STAMP"  # newer than its inputs again, for make
    echo "build_interfaces: ${PACKAGES[*]} up to date"
    exit 0
  fi
fi

# needed only when something is (re)built
for tool in cmake cc c++; do
  command -v "$tool" >/dev/null || fail "'$tool' not found: generating control_msgs needs CMake (>= 3.10) and a C/C++ compiler (Debian: apt-get install cmake g++)"
done
[ -d "$VENV/share/rosidl_default_generators" ] && [ -d "$VENV/share/ament_cmake" ] || \
  fail "the rosidl generators are not in $VENV: pip install -r requirements-build.txt -c constraints.txt"

# The type-support lookup reads the ament index from AMENT_PREFIX_PATH at configure time.
export AMENT_PREFIX_PATH="$VENV"
export CMAKE_PREFIX_PATH="$VENV"
export PATH="$VENV/bin:$PATH"
PY_INCLUDES="$("$PY" -c 'import sysconfig, numpy; print(sysconfig.get_paths()["include"] + ";" + numpy.get_include())')"

start=$(date +%s)
for pkg in "${PACKAGES[@]}"; do
  src="$ROOT/interfaces/$pkg"
  dir="$BUILD/$pkg"
  log="$BUILD/$pkg.log"
  rm -rf "$dir"
  mkdir -p "$dir"
  echo "build_interfaces: generating $pkg into $VENV (log: $log)"
  if ! { cmake -S "$src" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$VENV" \
           -DPython3_EXECUTABLE="$PY" -DPDSMC_PYTHON_INCLUDE_DIRS="$PY_INCLUDES" -DBUILD_TESTING=OFF \
         && cmake --build "$dir" -j "$(nproc)" \
         && cmake --install "$dir"; } >"$log" 2>&1; then
    tail -n 20 "$log" >&2
    fail "building $pkg failed; the full log is $log"
  fi
  # the import check runs in a fresh interpreter, as a user's would
  "$PY" -c "import importlib; importlib.import_module('$pkg.msg')" >>"$log" 2>&1 || {
    tail -n 20 "$log" >&2; fail "$pkg was installed but does not import; see $log"; }
done
rm -rf "$BUILD"
rmdir "$ROOT/build" 2>/dev/null || true
echo "$WANT" > "$STAMP"
echo "build_interfaces: ${PACKAGES[*]} built and installed in $(( $(date +%s) - start )) s"
