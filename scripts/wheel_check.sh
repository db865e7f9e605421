#!/usr/bin/env bash
# The package as a user gets it: build the wheel, install it into a fresh virtual environment
# (with constraints.txt, as setup.sh does), and from outside the source tree make the env and
# play one evaluation episode. A module or data file missing from the wheel fails here.
# WHEEL_CHECK_DIR: keep everything there (a new folder) instead of a temporary one.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -n "${WHEEL_CHECK_DIR:-}" ]; then
  [ ! -e "$WHEEL_CHECK_DIR" ] || { echo "WHEEL_CHECK_DIR $WHEEL_CHECK_DIR exists; expected a new folder" >&2; exit 2; }
  mkdir -p "$WHEEL_CHECK_DIR"
  OUT=$(realpath "$WHEEL_CHECK_DIR")
else
  OUT=$(mktemp -d /tmp/wheel-check.XXXXXX)  # outside the checkout: no .git above it
  trap 'rm -rf "$OUT"' EXIT
fi
echo "[wheel-check] building the wheel in $OUT"
.venv/bin/pip wheel -q --no-deps -w "$OUT/dist" . 2>&1 \
  | { grep -v -e "is ignored: it is neither a file nor a directory" || true; }
# the licences travel with the package: the code's LICENSE and the assets' ATTRIBUTION.md
python3 - "$OUT"/dist/*.whl <<'PY'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
for want in ("LICENSE", "ATTRIBUTION.md"):
    found = [n for n in names if ".dist-info/licenses/" in n and n.endswith(want)]
    assert found, f"the wheel has no {want} under .dist-info/licenses/"
meta = zipfile.ZipFile(sys.argv[1]).read(next(n for n in names if n.endswith(".dist-info/METADATA")))
assert b"License-Expression: Apache-2.0 AND CC-BY-3.0" in meta, "no licence expression"
print("[wheel-check] LICENSE and ATTRIBUTION.md are in the wheel's .dist-info/licenses/")
# the shipped learned teams travel as package data; experiments and training state stay out
for want in ("memory.yaml", "memory/setting_I/model.pt", "hangrcom/setting_II/model.pt",
             "perception/knowledge/model.pt", "segmenter-v2/model.pt",
             "segmenter-v2/model.int8.onnx"):
    assert f"maniskill_tidy/agents/{want}" in names, f"the wheel has no agents/{want}"
stray = [n for n in names if "/agents/experiments/" in n or n.endswith("checkpoint.pt")]
assert not stray, f"the wheel carries {stray[:3]}"
agents = sum(i.file_size for i in zipfile.ZipFile(sys.argv[1]).infolist()
             if i.filename.startswith("maniskill_tidy/agents/"))
assert agents < 60e6, f"the wheel's agents/ holds {agents / 1e6:.0f} MB; expected under 60"
print(f"[wheel-check] the shipped agents' configs and weights are in the wheel ({agents / 1e6:.0f} "
      "MB), experiments not")
PY
python3 -m venv "$OUT/venv"
echo "[wheel-check] installing $(basename "$OUT"/dist/*.whl) into a fresh venv"
"$OUT/venv/bin/pip" install -q -c constraints.txt "$OUT"/dist/*.whl 2>&1 \
  | { grep -v -e "is ignored: it is neither a file nor a directory" || true; }
mkdir -p "$OUT/myteam" && cp examples/wanderer.py "$OUT/myteam/"  # a team of the user's own
cd "$OUT"  # no source tree on the path from here
# an empty cache: the env reads SAPIEN's BRDF table back with the wheel's shader (sim/brdf_lut.py)
XDG_CACHE_HOME="$OUT/cache" venv/bin/python - <<'PY'
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
# an installed package has no checkout to name: the run records the package's version
# (in the default look, v2: its meshes and textures come with the wheel)
grep -q '"maniskill-tidy 0.1.0"' run/eval/results/setting_I/expert-v2/run.json
# a learned team from the weights the wheel ships (no agents/ here)
[ ! -e agents ] && venv/bin/maniskill-tidy eval --policy memory --setting I --episodes 1 --out run
grep -q '"episodes": 1' run/eval/results/setting_I/memory-v2/summary.json
# a team written in a folder of its own (docs/teams.md) plays by its import path, two workers
(cd myteam && ../venv/bin/maniskill-tidy eval --policy wanderer:WandererTeam --setting I \
  --episodes 2 --workers 2 --out run >/dev/null)
grep -q '"episodes": 2' myteam/run/eval/results/setting_I/wanderer-v2/summary.json
echo "[wheel-check] ok: the wheel's env, one expert and one memory episode and a user's own team run outside the source tree"
