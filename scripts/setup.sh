#!/usr/bin/env bash
# Idempotent set-up for a fresh Debian 12 machine: system packages, then a venv with the project.
# Safe to run repeatedly: each step checks what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}
SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"

need_apt=()
# SAPIEN renders through Vulkan; without a GPU that is Mesa's lavapipe, which must be >= 24.3
# (bookworm ships 22.3; bookworm-backports has a new enough one).
mesa_ok() {
  local v
  v=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
  [ -n "$v" ] && dpkg --compare-versions "$v" ge 24.3
}
mesa_ok || need_apt+=(mesa-vulkan-drivers)
for pkg in libusb-1.0-0 vulkan-tools libgl1 libegl1 libgomp1; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ] && command -v apt-get >/dev/null; then
  if . /etc/os-release && [ "${VERSION_CODENAME:-}" = bookworm ] \
     && ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    echo "deb http://deb.debian.org/debian bookworm-backports main" \
      | $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
  fi
  echo "[setup] apt: ${need_apt[*]}"
  $SUDO apt-get update -qq
  if grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq -t bookworm-backports \
      mesa-vulkan-drivers libvulkan1 >/dev/null
  fi
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
stamp="$VENV/.installed-$(cat pyproject.toml constraints.txt | sha1sum | cut -c1-12)"
if [ ! -f "$stamp" ]; then
  echo "[setup] pip install -e .[dev,docs,ray] (constraints.txt pins the CPU torch)"
  "$VENV/bin/pip" install -q --upgrade pip
  # pipefail keeps pip's exit status; the filter only drops this machine's local-index notices.
  "$VENV/bin/pip" install -q -c constraints.txt -e ".[dev,docs,ray]" 2>&1 \
    | { grep -v -e "is ignored: it is neither a file nor a directory" || true; }
  rm -f "$VENV"/.installed-*
  touch "$stamp"
fi
echo "[setup] ok: $("$VENV/bin/python" --version), mesa-vulkan-drivers $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || echo none)"
