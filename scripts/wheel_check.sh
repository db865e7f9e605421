#!/usr/bin/env bash
# The package as a user gets it: build the wheel, install it into a fresh virtual environment
# (with constraints.txt, as setup.sh does), and from outside the source tree make the env and
# play one evaluation episode. A module or data file missing from the wheel fails here.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=$(realpath -m "${OUT:-out/wheel-check}")
rm -rf "$OUT"
mkdir -p "$OUT"
echo "[wheel-check] building the wheel"
.venv/bin/pip wheel -q --no-deps --no-build-isolation -w "$OUT/dist" . 2>&1 \
  | { grep -v -e "is ignored: it is neither a file nor a directory" || true; }
python3 -m venv "$OUT/venv"
echo "[wheel-check] installing $(basename "$OUT"/dist/*.whl) into a fresh venv"
"$OUT/venv/bin/pip" install -q -c constraints.txt "$OUT"/dist/*.whl 2>&1 \
  | { grep -v -e "is ignored: it is neither a file nor a directory" || true; }
cd "$OUT"  # no source tree on the path from here
venv/bin/python - <<'PY'
import gymnasium as gym
import numpy as np

import maniskill_tidy

assert "/venv/" in maniskill_tidy.__file__, maniskill_tidy.__file__
for env_id in ("HeteroTidy-v1", "HeteroTidy-v2"):
    env = gym.make(env_id, setting="I", split="test", render_mode="rgb_array")
    env.reset(seed=0)
    env.step({"agent_0": 0, "agent_1": 3, "agent_2": 8})
    picture = np.asarray(env.render())
    assert picture.std() > 0, f"{env_id}: a blank picture"
    env.close()
    print(f"[wheel-check] {env_id}: made, reset, stepped and drawn from the wheel")
PY
venv/bin/maniskill-tidy eval --policy expert --setting I --episodes 1 --out run
test -f run/eval/results/setting_I/expert/summary.json
echo "[wheel-check] ok: the wheel's env and one eval episode run outside the source tree"
