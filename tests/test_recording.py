"""A recorded episode is a valid .rrd holding the entities the recording module promises."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

from maniskill_tidy.eval.runner import RunConfig, make_env, run_episode
from maniskill_tidy.policies import make_team
from maniskill_tidy.recording.episode_log import EpisodeRecorder


def _rerun() -> str:
    return shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))


def _printed(path: Path) -> str:
    """``rerun rrd print --verbose``: every entity and component of a recording."""
    return subprocess.run(
        [_rerun(), "rrd", "print", "--verbose", str(path)], capture_output=True, text=True
    ).stdout


def test_recording_holds_images_poses_messages_and_metrics(tmp_path):
    cfg = RunConfig("expert", "I", "test", None, 1)
    env = make_env(cfg, images=True)
    try:
        record = run_episode(env, make_team("expert"), 0, 0, EpisodeRecorder(tmp_path))
    finally:
        env.close()
    files = list(tmp_path.glob("*.rrd"))
    assert len(files) == 1 and not list(tmp_path.glob(".*tmp"))
    verify = subprocess.run([_rerun(), "rrd", "verify", str(files[0])], capture_output=True)
    assert verify.returncode == 0, verify.stderr
    printed = subprocess.run(
        [_rerun(), "rrd", "print", str(files[0])], capture_output=True, text=True
    ).stdout
    paths = set(re.findall(r"(/(?:world|agents|comm|metrics|episode|maps)[A-Za-z0-9_/]*)", printed))
    expected = {
        "/world/house/walls",
        "/world/house/furniture",
        "/world/objects",
        "/world/cameras",  # the segmentation legend
        "/comm/matrix",
        "/comm/groups",
        "/comm/values",
        "/metrics/reasonable",
        "/metrics/picked",
        "/episode/result",
        "/maps",  # the map class legend
        "/maps/team",
        "/world/maps",
    }
    for a in ("agent_0", "agent_1", "agent_2"):
        expected |= {
            f"/world/agents/{a}",
            f"/world/cameras/{a}",
            f"/world/cameras/{a}/rgb",
            f"/world/cameras/{a}/depth",
            f"/world/cameras/{a}/segmentation",
            f"/agents/{a}/held",
            f"/agents/{a}/action",
            f"/maps/{a}",
            f"/world/maps/{a}",
        }
    assert expected <= paths, sorted(expected - paths)
    assert record.length > 0


class LogSpy(EpisodeRecorder):
    """Keeps what was logged where, besides writing the recording."""

    def start(self, env, team, channel) -> None:
        super().start(env, team, channel)
        self.logged: list[tuple[str, tuple]] = []
        write = self.rec.log

        def log(path, *args, **kwargs):
            self.logged.append((path, args))
            return write(path, *args, **kwargs)

        self.rec.log = log


def test_a_learned_teams_recording_shows_t_and_its_handshake_groups(tmp_path, learned_config):
    """HanGrCom's communication matrix, each agent's row of it and its sub-task are logged,
    and comm/groups shows the handshake's groups (labelled), not all traffic."""
    team = make_team(str(learned_config))
    env = make_env(RunConfig(str(learned_config), "I", "test", None, 1), images=True)
    env.unwrapped.max_steps = 3
    recorder = LogSpy(tmp_path)
    try:
        run_episode(env, team, 0, 0, recorder)
    finally:
        env.close()
    (path,) = tmp_path.glob("*.rrd")
    printed = _printed(path)
    paths = set(re.findall(r"(/(?:agents|comm)[A-Za-z0-9_/]*)", printed))
    expected = {"/comm/T", "/comm/groups"} | {
        f"/agents/agent_{i}/{leaf}" for i in range(3) for leaf in ("attention", "subtask")
    }
    assert expected <= paths, sorted(expected - paths)
    nodes = [args[0] for where, args in recorder.logged if where == "comm/groups"]
    labels = [str(n.labels.as_arrow_array().to_pylist()) for n in nodes if hasattr(n, "labels")]
    assert len(labels) == 3 and all("(group 0)" in text for text in labels), labels


def test_the_memory_teams_recording_shows_each_choice_of_job(tmp_path):
    """The object-memory team's pointer logs what it chose (agents/NAME/choice) when it
    chooses: in the first step every agent chooses its first job."""
    env = make_env(RunConfig("memory", "I", "test", None, 1), images=True)
    env.unwrapped.max_steps = 2
    recorder = LogSpy(tmp_path)
    try:
        run_episode(env, make_team("memory"), 0, 0, recorder)
    finally:
        env.close()
    (path,) = tmp_path.glob("*.rrd")
    printed = _printed(path)
    paths = set(re.findall(r"(/agents/[A-Za-z0-9_]+/choice)", printed))
    assert paths == {f"/agents/agent_{i}/choice" for i in range(3)}
    texts = [str(args[0].text.as_arrow_array().to_pylist()) for where, args in recorder.logged
             if where.endswith("/choice")]  # fmt: skip
    assert texts and all(" candidates)" in t and "(p " in t for t in texts), texts
