"""Bad input gets one line naming what was wrong and what was expected, exit status 2, and
nothing half-written."""

from __future__ import annotations

import gzip
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from maniskill_tidy.envs.episodes import default_dataset


def cli(*args: str, cwd: Path | None = None, env: dict | None = None):
    return subprocess.run(
        [sys.executable, "-m", "maniskill_tidy.cli", *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=cwd,
        env={**os.environ, **(env or {})},
    )


def one_line_error(p: subprocess.CompletedProcess, *words: str) -> str:
    assert p.returncode == 2, (p.returncode, p.stderr[-2000:])
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.mark.parametrize("houses", ["0", "-1"])
def test_generate_refuses_no_houses(tmp_path, houses):
    out = tmp_path / "ds"
    one_line_error(cli("generate", "--houses", houses, "--out", str(out)), "--houses", "at least 1")
    assert not out.exists()


def test_validate_flags_a_dataset_without_houses(tmp_path):
    out = tmp_path / "empty"
    out.mkdir()
    (out / "manifest.json").write_text(
        json.dumps({"schema_version": "1.0", "files": {}, "dataset_hash": "x"})
    )
    p = cli("validate", str(out))
    assert p.returncode != 0 and "no houses" in p.stdout


def _copy_default(tmp_path: Path) -> Path:
    out = tmp_path / "ds"
    shutil.copytree(default_dataset(), out)
    return out


def test_eval_refuses_a_tampered_shard_naming_it(tmp_path):
    ds = _copy_default(tmp_path)
    shard = ds / "test" / "shard-0000.json.gz"
    payload = json.loads(gzip.decompress(shard.read_bytes()))
    payload["tasks"][0]["k"] += 1  # still a valid shard: only the hash can tell
    shard.write_bytes(gzip.compress(json.dumps(payload).encode()))
    p = cli("eval", "--policy", "expert", "--dataset", str(ds), "--out", str(tmp_path / "o"))
    one_line_error(p, "test/shard-0000.json.gz", "sha256")
    assert not (tmp_path / "o").exists()


def test_eval_on_a_missing_or_truncated_dataset_is_one_line(tmp_path):
    p = cli("eval", "--policy", "expert", "--dataset", str(tmp_path / "nowhere"))
    one_line_error(p, "manifest.json")
    ds = _copy_default(tmp_path)
    shard = ds / "test" / "shard-0000.json.gz"
    shard.write_bytes(shard.read_bytes()[:200])
    one_line_error(cli("eval", "--policy", "expert", "--dataset", str(ds)), "shard-0000")
    (ds / "test" / "shard-0000.json.gz").unlink()
    one_line_error(cli("eval", "--policy", "expert", "--dataset", str(ds)), "missing")


def test_eval_refuses_bad_arguments(tmp_path):
    one_line_error(cli("eval", "--policy", "nobody"), "unknown policy")
    one_line_error(cli("eval", "--policy", "expert", "--episodes", "x"), "--episodes")
    one_line_error(cli("eval", "--policy", "expert", "--setting", "III"), "unknown setting")


def test_replay_verifies_the_recording_first(tmp_path):
    bad = tmp_path / "broken.rrd"
    bad.write_bytes(b"RRF2" + b"\x00garbage" * 100)
    one_line_error(cli("replay", str(bad)), "damaged")
    one_line_error(cli("replay", str(tmp_path / "none.rrd")), "not an .rrd recording")


def test_replay_without_a_display_serves_the_web_viewer_on_this_machine_only(tmp_path):
    """A fake ``rerun`` first on the PATH records how it is called."""
    fake = tmp_path / "bin" / "rerun"
    fake.parent.mkdir()
    fake.write_text(f'#!/bin/sh\necho "$@" >> {tmp_path / "calls"}\n')
    fake.chmod(0o755)
    rrd = tmp_path / "episode.rrd"
    rrd.write_bytes(b"RRF2")
    env = {"PATH": f"{fake.parent}:{os.environ['PATH']}", "DISPLAY": "", "WAYLAND_DISPLAY": ""}
    p = cli("replay", str(rrd), env=env)
    assert p.returncode == 0, p.stderr
    assert "no display" in p.stdout and "127.0.0.1" in p.stdout
    calls = (tmp_path / "calls").read_text().splitlines()
    assert calls == [f"rrd verify {rrd}", f"{rrd} --web-viewer --bind 127.0.0.1"]
    p = cli("replay", str(rrd), "--bind", "0.0.0.0", env={**env, "DISPLAY": ":0"})
    assert (tmp_path / "calls").read_text().splitlines()[-1] == str(rrd)  # a native window


def test_a_malformed_agent_config_is_refused_in_one_line(tmp_path):
    bad = tmp_path / "agent.yaml"
    bad.write_text("trainer: memory\nmodel: [unclosed\n")
    one_line_error(cli("eval", "--policy", str(bad), "--setting", "I"), str(bad),
                   "not valid YAML", "line")  # fmt: skip


def test_a_team_preset_error_names_the_file(tmp_path):
    preset = tmp_path / "team.json"
    preset.write_text(json.dumps({"team": [[1, 0, 0], [0, 1, 1]]}))
    one_line_error(
        cli("eval", "--policy", "expert", "--setting", str(preset)), str(preset), "Nav=1"
    )


def test_train_refuses_a_folder_that_is_not_a_dataset(tmp_path):
    one_line_error(
        cli("train", "perception", "--dataset", str(tmp_path), "--out", str(tmp_path / "a")),
        "manifest.json",
    )
    assert not (tmp_path / "a").exists()


def test_train_refuses_encoder_widths_that_are_not_four_channel_counts(tmp_path):
    for bad in ("16,32,48", "16,32,x,64", "16,0,48,64"):
        one_line_error(
            cli("train", "perception", "--visual-widths", bad, "--out", str(tmp_path / "a")),
            "--visual-widths", "four positive channel counts",
        )  # fmt: skip
    assert not (tmp_path / "a").exists()


def test_perception_report_without_agents_names_the_command(tmp_path):
    one_line_error(
        cli("perception-report", "--agents", str(tmp_path / "none"), "--work", str(tmp_path)),
        "card.json",
        "train perception",
    )


def test_the_policies_command_lists_every_team():
    from maniskill_tidy.policies import POLICIES

    p = cli("policies")
    assert p.returncode == 0, p.stderr
    assert [line.split()[0] for line in p.stdout.splitlines()] == list(POLICIES)


def test_eval_of_an_untrained_variant_names_the_training_command_and_writes_nothing(tmp_path):
    config = tmp_path / "untrained.yaml"
    config.write_text(
        f"base: {Path('agents/hangrcom.yaml').resolve()}\nname: untrained\n"
        f"out: {tmp_path / 'nowhere'}\n"
    )
    out = tmp_path / "run"
    line = one_line_error(cli("eval", "--policy", str(config), "--out", str(out)), "not found")
    assert f"maniskill-tidy train {config} --setting I" in line
    assert not out.exists()


def test_a_job_that_kills_its_workers_ends_the_command_in_one_line_with_status_1(
    tmp_path, monkeypatch, capsys
):
    from maniskill_tidy import cli as cli_module
    from maniskill_tidy.common.parallel import WorkerLostError

    def lose_workers(args):
        raise WorkerLostError("job 'h007' lost 3 Ray workers in a row; stopping")

    monkeypatch.setattr(cli_module.dataset, "_generate", lose_workers)
    status = cli_module.main(["generate", "--houses", "2", "--out", str(tmp_path / "ds")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert status == 1
    assert lines == ["maniskill-tidy generate: job 'h007' lost 3 Ray workers in a row; stopping"]


def test_a_bug_inside_a_job_ends_the_command_with_its_traceback_and_status_1(
    tmp_path, monkeypatch, capsys
):
    """A stale-id KeyError inside an episode once came out as "maniskill-tidy eval: Statue_0",
    exit 2: a bug reported as bad input, with nothing to say where."""
    from maniskill_tidy import cli as cli_module
    from maniskill_tidy.tasks import dataset

    def stale_id(args):
        return {"CD_1": 1}["Statue_0"]

    monkeypatch.setattr(dataset, "_make_shard", stale_id)
    status = cli_module.main(["generate", "--houses", "2", "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err.strip()
    assert status == 1
    assert "Traceback" in err and "in stale_id" in err
    last = err.splitlines()[-1]
    assert last.startswith("maniskill-tidy generate: job (0, 'train', 0, ")
    assert last.endswith("failed: KeyError: 'Statue_0' (traceback above)")


def test_bad_input_found_inside_a_job_is_still_one_line_with_status_2(
    tmp_path, monkeypatch, capsys
):
    from maniskill_tidy import cli as cli_module
    from maniskill_tidy.tasks import dataset

    def damaged(args):
        raise dataset.DatasetError("shard-0000.json.gz: damaged; expected gzip JSON")

    monkeypatch.setattr(dataset, "_make_shard", damaged)
    status = cli_module.main(["generate", "--houses", "2", "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert "Traceback" not in err  # above the line: only the progress bar, closed
    assert err.splitlines()[-1] == (
        "maniskill-tidy generate: shard-0000.json.gz: damaged; expected gzip JSON"
    )


def test_training_an_agent_config_refuses_the_perception_options_instead_of_ignoring_them(
    tmp_path,
):
    """`train CONFIG --out X` once wrote the shipped model over, since only the config says
    where a model goes (and eval reads it there)."""
    config = tmp_path / "variant.yaml"
    config.write_text(f"base: {Path('agents/hangrcom.yaml').resolve()}\nname: v\nout: {tmp_path}\n")
    out = tmp_path / "elsewhere"
    line = one_line_error(cli("train", str(config), "--out", str(out)), "--out", "base:")
    assert str(config) in line
    assert not out.exists() and not (tmp_path / "setting_I").exists()


def test_compare_refuses_a_folder_without_episodes_and_runs_with_nothing_in_common(tmp_path):
    one_line_error(cli("compare", str(tmp_path / "nowhere"), str(tmp_path)), "nowhere",
                   "episodes.jsonl")  # fmt: skip
    line = {"task_kind": "Single", "k": 1, "success": True, "reasonable": 1, "found": 1,
            "length": 9, "comm": 0, "agents": 3, "seed": 0}  # fmt: skip
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        record = json.dumps({**line, "episode": f"only-{name}"})
        (tmp_path / name / "episodes.jsonl").write_text(record + "\n")
    one_line_error(cli("compare", str(tmp_path / "a"), str(tmp_path / "b")), "no episode in common")


def test_compare_prints_objects_placed_and_failed_actions_of_both_runs(tmp_path):
    line = {"task_kind": "Single", "k": 2, "success": False, "reasonable": 1, "found": 1,
            "length": 10, "comm": 0, "agents": 3, "seed": 0}  # fmt: skip
    for name, placed, failed in (("a", (2, 1), (4, 6)), ("b", (0, 1), (0, 1))):
        (tmp_path / name).mkdir()
        pairs = enumerate(zip(placed, failed, strict=True))
        rows = [{**line, "episode": f"e{i}", "reasonable": p, "success": p == 2,
                 "failed_actions": f} for i, (p, f) in pairs]  # fmt: skip
        (tmp_path / name / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    p = cli("compare", str(tmp_path / "a"), str(tmp_path / "b"))
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    totals = {ln.split()[0]: ln.split()[1:] for ln in lines[-3:-1]}  # the run table's two rows
    assert totals["A"] == ["3", "/", "4", "5.0", "of", "30"]
    assert totals["B"] == ["1", "/", "4", "0.5", "of", "30"]
    assert lines[-1] == "same Success on 1 of 2 episodes; 0 records identical (all but wall time)"


@pytest.mark.parametrize("card", ["with", "without"])
def test_eval_refuses_a_damaged_checkpoint_before_writing(tmp_path, card):
    """A truncated model.pt: with its card, its sha256 differs; without, torch cannot read it.
    Either way one line, status 2, and no run folder."""
    repo = Path(__file__).resolve().parents[1]
    agent = tmp_path / "agent"
    shutil.copytree(repo / "agents" / "hangrcom" / "setting_I", agent / "setting_I")
    weights = agent / "setting_I" / "model.pt"
    weights.write_bytes(weights.read_bytes()[:4096])
    if card == "without":
        (agent / "setting_I" / "card.json").unlink()
    config = tmp_path / "damaged.yaml"
    config.write_text(f"base: {repo / 'agents' / 'hangrcom.yaml'}\nname: damaged\nout: {agent}\n")
    out = tmp_path / "out"
    p = cli("eval", "--policy", str(config), "--setting", "I", "--episodes", "1", "--out", str(out))
    words = ("sha256", "retrain") if card == "with" else ("not a readable checkpoint",)
    # both commands that make it: this variant's, and the one that trains every variant
    one_line_error(p, str(weights), *words, "--setting I` (or `make train-all`)")
    assert not out.exists()


def test_leaderboard_refuses_a_root_without_runs(tmp_path):
    root = tmp_path / "nonexistent"
    one_line_error(cli("leaderboard", "--root", str(root)), str(root), "no eval runs")
    assert not root.exists()


@pytest.mark.parametrize("command", [["eval", "--policy", "random"], ["generate", "--houses", "1"]])
def test_workers_below_one_are_refused(tmp_path, command):
    out = tmp_path / "out"
    p = cli(*command, "--workers", "0", "--out", str(out))
    one_line_error(p, "--workers 0", "at least 1")
    assert not out.exists()


def test_eval_workers_take_a_number_or_auto(tmp_path):
    out = tmp_path / "out"
    p = cli("eval", "--policy", "random", "--workers", "many", "--out", str(out))
    one_line_error(p, "--workers 'many'", "a number of processes or auto")
    assert not out.exists()


def test_a_bad_agent_processes_knob_is_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "out"
    p = cli("eval", "--policy", "random", "--out", str(out), env={"TIDY_AGENT_PROCESSES": "on"})
    one_line_error(p, "TIDY_AGENT_PROCESSES='on'", "expected 0 or 1")
    assert not out.exists()


def test_the_cross_look_table_refuses_missing_frames_and_weights(tmp_path):
    out = tmp_path / "table"
    p = cli("segmenter-cross-look", "--segmenters", str(tmp_path / "none"), "--data",
            str(tmp_path), "--out", str(out))  # fmt: skip
    one_line_error(p, str(tmp_path), "no <look>/test/manifest.json", "make segmenter-data")
    (tmp_path / "HeteroTidy-v2" / "test").mkdir(parents=True)
    (tmp_path / "HeteroTidy-v2" / "test" / "manifest.json").write_text("{}")
    p = cli("segmenter-cross-look", "--segmenters", str(tmp_path / "none"), "--data",
            str(tmp_path), "--out", str(out))  # fmt: skip
    one_line_error(p, "model.pt not found", "train-segmenter")
    assert not out.with_suffix(".json").exists() and not out.with_suffix(".md").exists()


@pytest.mark.parametrize(("option", "value"), [("--focus", "1.5"), ("--zoom", "0.5"),
                                              ("--lr", "0"), ("--init", "agents/none")])
def test_train_segmenter_refuses_options_out_of_range_before_reading_frames(tmp_path, option,
                                                                           value):  # fmt: skip
    out = tmp_path / "seg"
    p = cli("train-segmenter", "--data", str(tmp_path / "none"), "--out", str(out), option, value)
    one_line_error(p, option, "expected")
    assert not out.exists()


def test_quantize_segmenter_refuses_a_folder_without_a_trained_segmenter(tmp_path):
    p = cli("quantize-segmenter", "--segmenter", str(tmp_path / "none"), "--data", str(tmp_path))
    one_line_error(p, "card.json not found", "train-segmenter")
    assert not (tmp_path / "none").exists()
