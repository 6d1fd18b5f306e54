#!/usr/bin/env bash
# Installs what a fresh Debian machine needs to build and test everything:
# libudev (serialport, probe-rs), Chromium (the evidence report's headless
# browser test), QEMU for Arm (the firmware's cycle budget, ci/cycle-budget.py),
# Python fixtures' packages (MAVSDK among them; and MAVProxy), the firmware's Rust target. Safe to run again: it skips what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
for pkg in pkg-config libudev-dev chromium qemu-system-arm; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
    echo "setup: apt-get install ${need_apt[*]}"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

if ! python3 -c "import serial, pymavlink, pytest, xdist, mavsdk" 2>/dev/null; then
    echo "setup: pip install -r fixtures/requirements.txt"
    python3 -m pip install -q --disable-pip-version-check -r fixtures/requirements.txt
fi
# MAVProxy, the real ground station of firmware/mavlora/tests/e2e_mavproxy.rs, without its
# declared dependencies (vtk, opencv, matplotlib, numpy: its GUI, maps and terrain); the
# console modules the test loads need only pymavlink and pyserial, installed just above.
if ! { command -v mavproxy.py >/dev/null && python3 -c "import MAVProxy" 2>/dev/null; }; then
    echo "setup: pip install --no-deps -r fixtures/requirements-mavproxy.txt"
    python3 -m pip install -q --disable-pip-version-check --no-deps -r fixtures/requirements-mavproxy.txt
    command -v mavproxy.py >/dev/null \
        || echo "setup: warning: mavproxy.py is installed but not on PATH (pip's scripts folder): e2e_mavproxy will fail" >&2
fi

# rust-toolchain.toml names the toolchain and the thumbv6m target; this makes
# rustup install whatever of it is missing before cargo needs it.
rustup show active-toolchain >/dev/null
rustup target list --installed | grep -qx thumbv6m-none-eabi || rustup target add thumbv6m-none-eabi
