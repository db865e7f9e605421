"""The render-backend comparison (`check-render`): what it counts, and lavapipe against itself."""

from __future__ import annotations

import numpy as np
import pytest

from maniskill_tidy.envs.hetero_tidy import default_render_backend
from maniskill_tidy.eval.backend_check import BackendComparison, TwinObserver, compare_backends
from tests.test_cli_errors import cli, one_line_error


class _FakeTwin:
    def __init__(self, frames):
        self.frames = iter(frames)

    def call(self, what, arg):
        return next(self.frames)


class _Env:
    class episode:  # noqa: N801
        id = "house_x/task_0/start_0"


def _obs(seg, held=0):
    return {"agent_0": {"segmentation": seg, "depth": np.ones_like(seg, np.float32),
                        "held": np.array(held)}}  # fmt: skip


def test_the_comparison_counts_what_decides_outcomes():
    seg = np.zeros((16, 16), np.int32)
    seg[:5, :5] = 7  # 25 px: visible
    other = seg.copy()
    other[:5, :5] = 0  # the twin does not see instance 7
    result = BackendComparison(("cpu", "gpu"))
    twin = TwinObserver(_FakeTwin([(_obs(seg), {}), (_obs(other, 7), {})]), 0, 0, result)
    twin.start(_Env(), None, None)
    twin.observed(0, _obs(seg), {"failed": {}})  # the same frame
    twin.decided(0, {}, {})
    twin.observed(1, _obs(seg), {"failed": {"agent_0": "not visible"}})
    s = result.summary()
    assert s["agent_steps"] == 2 and s["visible_differs"] == 1 and s["outcome_differs"] == 1
    assert s["first_divergence"] == ["house_x/task_0/start_0 step 1 agent_0: visible [7]; "
                                     "outcome 'not visible'/0 vs ''/7"]  # fmt: skip
    assert s["pixel_agreement_min"] == pytest.approx(1 - 25 / 256)
    # the 5 x 5 block sits in the corner: its rim is its last row and column, 9 pixels
    assert s["pixels_differ"] == 25 and s["pixels_differ_on_edges"] == 9


def test_lavapipe_against_itself_shows_no_difference():
    r = compare_backends(("cpu", "cpu"), episodes=1, progress=False).summary()
    assert r["episodes"] == 1 and r["agent_steps"] > 50
    assert r["visible_differs"] == r["outcome_differs"] == 0
    assert r["pixel_agreement_min"] == 1.0


@pytest.mark.skipif(default_render_backend() == "gpu", reason="this machine has a CUDA device")
def test_check_render_without_a_gpu_says_so_in_one_line():
    one_line_error(cli("check-render", "--episodes", "1"), "no CUDA device", "cpu,cpu")
    one_line_error(cli("check-render", "--backends", "cpu,vulkan"), "expected two of cpu, gpu")
    one_line_error(cli("check-render", "--save", "x", "--backend", "gpu"), "no CUDA device")


def test_a_trace_replayed_on_the_same_backend_agrees_and_a_changed_one_does_not(tmp_path):
    """The cross-machine path (`check-render --save` here, `--against` there), on lavapipe."""
    from maniskill_tidy.eval.backend_check import compare_with_trace, record_trace

    meta = record_trace(tmp_path, "cpu", episodes=1, progress=False)
    same = compare_with_trace(tmp_path, "cpu", progress=False).summary()
    assert same["episodes"] == 1 and same["agent_steps"] > 50
    assert same["visible_differs"] == same["outcome_differs"] == 0
    assert same["pixel_agreement_min"] == 1.0 and same["depth_median_abs_max_m"] == 0.0

    path = tmp_path / meta["files"][0]
    with np.load(path) as z:
        arrays = dict(z)
    seg = arrays["segmentation"]
    t, a = 1, 0
    ids, counts = np.unique(seg[t, a], return_counts=True)
    gone = int(ids[(ids > 0) & (counts >= 20)][0])  # an instance the first agent sees at step 1
    seg[t, a][seg[t, a] == gone] = 0
    arrays["held"][t + 1, a] = 12345  # and an outcome the replay cannot reproduce
    np.savez_compressed(path, **arrays)
    changed = compare_with_trace(tmp_path, "cpu", progress=False).summary()
    assert changed["visible_differs"] >= 1 and changed["outcome_differs"] >= 1
    assert changed["pixel_agreement_min"] < 1.0
    assert f"step {t + 1} agent_0" in changed["first_divergence"][0]


def test_check_render_against_a_folder_without_a_trace_says_so_in_one_line(tmp_path):
    one_line_error(cli("check-render", "--against", str(tmp_path)), "no trace.json", "--save")
