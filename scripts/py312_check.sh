#!/usr/bin/env bash
# Does every requirement of the package have a Python 3.12 wheel for x86-64 Linux? These
# machines have no 3.12 interpreter (none of the reachable registries ships one), so pip
# resolves the package's direct requirements for 3.12 without installing them (--dry-run),
# under constraints.txt. The full transitive set cannot be resolved here: torch's CUDA
# wheels for 3.12 name nvidia-* packages this machine's registry mirror lacks.
set -euo pipefail
cd "$(dirname "$0")/.."
platforms=()
for v in 36 35 34 33 32 31 30 29 28 27 26 25 24 17; do platforms+=(--platform "manylinux_2_${v}_x86_64"); done
mapfile -t reqs < <(.venv/bin/python -c "
import tomllib
for r in tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies']:
    print(r)")
.venv/bin/pip install --dry-run --no-deps --ignore-installed --python-version 3.12 \
  "${platforms[@]}" --platform manylinux2014_x86_64 --platform linux_x86_64 --only-binary=:all: \
  -c constraints.txt "${reqs[@]}" 2>&1 | grep -e "^Would install" -e "^ERROR"
