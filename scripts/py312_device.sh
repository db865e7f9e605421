#!/usr/bin/env bash
# On a machine with Python 3.12 and no registry (the lent GPU machine): `pip install .` into a
# fresh venv, then generate and validate a small dataset with the installed package, from
# outside the source tree. The simulator's wheels (sapien, mani-skill, open3d) are too large
# to carry there, so the env itself is not made; scripts/py312_check.sh shows they exist for 3.12.
# Usage there: bash scripts/py312_device.sh (with .whl/ holding gymnasium's wheels).
set -euo pipefail
python3 --version
python3 -m venv /tmp/v312
# the machine's own numpy, scipy, torch... (its python3 is itself a venv, so
# --system-site-packages would not reach them): a .pth file names their folder
python3 -c "import site; print(site.getsitepackages()[0])" \
  > "$(/tmp/v312/bin/python -c 'import site; print(site.getsitepackages()[0])')/machine.pth"
/tmp/v312/bin/pip install -q --no-index --no-deps .whl/*.whl  # gymnasium, setuptools>=77
/tmp/v312/bin/pip install --no-index --no-deps --no-build-isolation . 2>&1 | tail -2
cd /tmp
/tmp/v312/bin/python - <<'PY'
import sys

import maniskill_tidy

print(sys.version.split()[0], maniskill_tidy.__file__)
PY
/tmp/v312/bin/python -m compileall -q "$(/tmp/v312/bin/python -c 'import maniskill_tidy, os; print(os.path.dirname(maniskill_tidy.__file__))')" && echo "compileall: every module compiles under 3.12"
/tmp/v312/bin/maniskill-tidy generate --houses 3 --seed 0 --out /tmp/ds312
/tmp/v312/bin/maniskill-tidy validate /tmp/ds312 | tail -2
