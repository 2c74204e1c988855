#!/usr/bin/env bash
# Idempotent set-up of lomanip on Debian 12 / Python 3.11: apt packages (when root), .venv,
# pinned Python dependencies, the interface build, and the lomanip packages. Each step is skipped
# when a stamp says its inputs have not changed, so a second run takes about a second.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
PY=${PYTHON:-python3}
STAMPS=$VENV/.lomanip-stamps

APT_PACKAGES="cmake g++ make libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgles2 libosmesa6 libusb-1.0-0 libgomp1"

say() { printf '[setup] %s\n' "$*"; }
digest() { cat "$@" | sha256sum | cut -c1-16; }

# 1. System packages (only when root and something is missing).
missing=""
for p in $APT_PACKAGES; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  if [ "$(id -u)" = 0 ]; then
    say "apt-get install$missing"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >/dev/null
  else
    say "WARNING: missing Debian packages (run as root or install them):$missing"
  fi
fi

# 2. Virtual environment.
if [ ! -x "$VENV/bin/python" ]; then
  "$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), "lomanip needs Python 3.11, found " + sys.version.split()[0]'
  say "creating .venv"
  "$PY" -m venv "$VENV"
fi
mkdir -p "$STAMPS"

# 3. Pinned Python dependencies.
req=$(digest requirements.txt)
if [ "$(cat "$STAMPS/requirements" 2>/dev/null)" != "$req" ]; then
  # The wheels unpack to about 4 GB (torch, open3d, mujoco); stop early with one clear line rather
  # than half-install when the disk is nearly full.
  free_kb=$(df -Pk "$VENV" | awk 'NR==2 {print $4}')
  if [ "${free_kb:-0}" -lt 6000000 ]; then
    say "ERROR: only $((free_kb / 1024)) MB free on the disk of $VENV; the Python dependencies need about 6 GB"
    exit 1
  fi
  say "installing Python dependencies (first time: a few minutes)"
  # grep finds nothing to print when pip is quiet (exit 1): only pip's own status counts
  set +e
  "$VENV/bin/pip" install -q --no-cache-dir --disable-pip-version-check -r requirements.txt 2>&1 \
    | { grep -v "is ignored: it is neither" || true; }
  pip_rc=${PIPESTATUS[0]}
  set -e
  if [ "$pip_rc" != 0 ]; then say "ERROR: pip install -r requirements.txt failed (exit $pip_rc; see above)"; exit 1; fi
  "$VENV/bin/python" -c 'import rclpy, mujoco, casadi, pinocchio, rosbags' 
  echo "$req" > "$STAMPS/requirements"
fi

# 4. Interfaces (rosidl with cmake, installed into the venv prefix).
build_iface() {  # name source_dir
  local name=$1 src=$2 stamp
  stamp=$(digest requirements.txt $(find "$src" -type f | sort))
  if [ "$(cat "$STAMPS/iface-$name" 2>/dev/null)" = "$stamp" ]; then return; fi
  say "building interfaces: $name"
  local b=$ROOT/build/$name
  rm -rf "$b" && mkdir -p "$b"
  ( cd "$b" && PATH=$VENV/bin:$PATH cmake "$src" -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" \
      -DAMENT_PREFIX_PATH="$VENV" -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF \
      -DLOMANIP_FILTER_WHEEL_INCLUDES=ON >cmake.log 2>&1 \
    && PATH=$VENV/bin:$PATH make -j"$(nproc)" >make.log 2>&1 && make install >install.log 2>&1 ) \
    || { say "interface build of $name failed; see $b/*.log"; tail -20 "$b"/make.log 2>/dev/null; exit 1; }
  echo "$stamp" > "$STAMPS/iface-$name"
}
if ! "$VENV/bin/python" -c 'import tf2_msgs.msg' 2>/dev/null || [ -f "$STAMPS/iface-tf2_msgs" ]; then
  build_iface tf2_msgs "$ROOT/ros_ws/interfaces/tf2_msgs"
fi
build_iface lomanip_msgs "$ROOT/src/lomanip_msgs"

# 5. lomanip Python packages (editable, so the checkout is what runs).
pk=$(digest $(ls src/*/setup.py ros_ws/*/setup.py))
if [ "$(cat "$STAMPS/packages" 2>/dev/null)" != "$pk" ]; then
  say "installing lomanip packages"
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation \
    $(for d in src/lomanip_sim src/lomanip_to src/lomanip_perception src/lomanip_planner ros_ws/lomanip_launch; do printf -- '-e %s ' "$d"; done) \
    2>&1 | grep -v "is ignored: it is neither" || true
  echo "$pk" > "$STAMPS/packages"
fi
say "ready"
