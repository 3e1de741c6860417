#!/usr/bin/env bash
# One-time set-up: system libraries for headless rendering, then a virtual
# environment with ambulo and everything its demo and tests use.
# Idempotent: re-running only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

# Headless GL: ambulo chooses at the first render (ambulo/render/gl.py): MUJOCO_GL if set, else
# EGL (a GPU's, or Mesa's llvmpipe) if libEGL loads, else OSMesa. Without either, everything but
# rendering still works and a render fails in one line naming these packages.
# libusb-1.0: Open3D's wheel (the perception extra) links it even without a camera attached.
need_apt=()
for lib in libEGL.so.1 libGL.so.1 libOSMesa.so.8 libusb-1.0.so.0; do
  ldconfig -p 2>/dev/null | grep -q "$lib" || need_apt+=("$lib")
done
if [ ${#need_apt[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing headless GL libraries (missing: ${need_apt[*]})"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libegl1 libgl1 libgles2 libosmesa6 libglx-mesa0 libusb-1.0-0 >/dev/null
  else
    echo "warning: missing ${need_apt[*]}; install libegl1 libgl1 libosmesa6 (Debian/Ubuntu) for headless rendering" >&2
  fi
fi

# The ROS 2 tests run in a loopback-only network namespace: `unshare -n` (util-linux) + `ip` (iproute2).
if ! command -v ip >/dev/null || ! command -v unshare >/dev/null; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing iproute2 and util-linux (loopback-only network namespaces for the ROS 2 tests)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq iproute2 util-linux >/dev/null
  else
    echo "warning: no 'ip'/'unshare'; the ROS 2 tests fall back to localhost-only discovery" >&2
  fi
fi

# The path-traced camera tier (ambulo/render/path.py): Mitsuba's LLVM variant JIT-compiles with
# libLLVM >= 16 (Debian 12 ships 15 by default; libllvm19 is in bookworm/main). Without it the path
# tier fails in one line naming this package; the CUDA variant needs no LLVM.
if ! ldconfig -p 2>/dev/null | grep -qE 'libLLVM(-1[6-9]|-2[0-9]|\.so\.(1[6-9]|2[0-9]))'; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing libllvm19 (Mitsuba's CPU path tracer)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null
  else
    echo "warning: no libLLVM >= 16; install libllvm19 (Debian/Ubuntu) for the path-traced camera tier" >&2
  fi
fi

# The PBR camera tier (ambulo/render/pbr.py): MuJoCo's Filament renderer draws through Vulkan; on a
# machine without a GPU driver Mesa's lavapipe (mesa-vulkan-drivers) renders on the CPU. Without the
# loader or a driver the pbr tier fails in one line naming these packages.
if ! ldconfig -p 2>/dev/null | grep -q 'libvulkan.so.1' || ! ls /usr/share/vulkan/icd.d/*.json >/dev/null 2>&1; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing libvulkan1 and mesa-vulkan-drivers (the Filament PBR camera tier)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libvulkan1 mesa-vulkan-drivers >/dev/null
  else
    echo "warning: no Vulkan; install libvulkan1 mesa-vulkan-drivers (Debian/Ubuntu) for the PBR camera tier" >&2
  fi
fi

# The web viewer's page test (tests/viewer) opens the page in headless Chromium, Debian's build
# (Playwright's own browser download is not used); WebGL runs on its SwiftShader rasterizer.
if ! command -v chromium >/dev/null; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    echo "installing chromium (the web viewer's page test)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  else
    echo "warning: no chromium; install it (Debian/Ubuntu) for the web viewer's page test" >&2
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi
stamp="$VENV/.ambulo-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  # The environment takes ~5 GB (torch, Open3D, Mitsuba, MuJoCo Warp, ROS 2 wheels) plus pip's unpacking
  # room; a disk that fills mid-install leaves a half-built venv and a pip OSError deep in the output.
  # (an update of an installed venv, pyproject.toml newer than its stamp, needs far less)
  if [ -f "$stamp" ]; then default_mb=1500; else default_mb=6500; fi
  need_mb=${AMBULO_SETUP_FREE_MB:-$default_mb}
  for dir in "$VENV" "${TMPDIR:-/tmp}"; do
    free_mb=$(df -Pm "$dir" 2>/dev/null | awk 'NR==2 {print $4}')
    if [ -n "$free_mb" ] && [ "$free_mb" -lt "$need_mb" ]; then
      echo "error: set-up needs ~${need_mb} MB free on the disk of $dir, which has ${free_mb} MB; free some space (AMBULO_SETUP_FREE_MB=0 skips this check) and re-run" >&2
      exit 1
    fi
  done
  "$VENV/bin/python" -m pip install -q --upgrade pip
  # the CPU build of torch first, pinned, so nothing pulls a multi-GB CUDA build
  "$VENV/bin/python" -m pip install -q "torch==${TORCH_VERSION:-2.13.0}"
  "$VENV/bin/python" -m pip install -q -e ".[data,rl,dev,robots,gpu,ros2,perception,render,isaacgym]"
  # rl_games for Isaac Gym scripts, without its pins (see the isaacgym extra in pyproject.toml)
  "$VENV/bin/python" -m pip install -q --no-deps "rl-games==1.6.5"
  touch "$stamp"
fi
echo "ambulo is set up in $VENV"
