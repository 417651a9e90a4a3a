#!/usr/bin/env bash
# Installs the system packages smartagg needs on a Debian/Ubuntu machine
# (skipped when they are all present). Run by scripts/demo.sh and
# scripts/test.sh, so that the README's two commands work on a fresh machine.
# As root (or with password-less sudo) it installs them with apt-get; otherwise
# it prints the exact command to run and stops.
#   pkg-config, libfontconfig1-dev, libfreetype-dev, fonts-dejavu-core: PNG plots
#   verilator, g++, make: the co-simulation of the generated Verilog
#   iverilog: the 4-state (Icarus Verilog) run of the XEM6310 core (sim/tests/icarus.rs)
#   yosys: synthesis figures (`smartagg hdl resources`) and its tests
#   python3: the second packet decoder, tools/rois.py, and its test (host/tests/python_decoder.rs)
#   libusb-1.0-0-dev: the USB bulk transport
#   shellcheck: the lint of the Slurm scripts in tools/slurm (host/tests/slurm.rs)
#   libhdf5-dev: Picasso HDF5 tables (`localize --out x.hdf5`, `render x.hdf5`; the hdf5-metno crate links it)
#   python3-h5py, python3-yaml: reading them back as Picasso does (host/tests/picasso.rs)
set -euo pipefail
PKGS=(pkg-config libfontconfig1-dev libfreetype-dev fonts-dejavu-core verilator g++ make iverilog yosys libusb-1.0-0-dev python3 shellcheck libhdf5-dev python3-h5py python3-yaml)
missing=()
for p in "${PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    if ! command -v apt-get >/dev/null; then
        echo "smartagg needs these packages (Debian names): ${missing[*]}" >&2
        echo "this machine has no apt-get: install their equivalents, then run this command again" >&2
        exit 1
    fi
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then
        if ! sudo -n true 2>/dev/null; then
            echo "smartagg needs packages that are not installed; as root, run:" >&2
            echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
            exit 1
        fi
        SUDO="sudo"
    fi
    echo "== installing: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
command -v cargo >/dev/null || { echo "smartagg needs Rust (cargo): https://rustup.rs" >&2; exit 1; }
