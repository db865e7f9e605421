"""What batching the agents' perception would buy, and what it would change (issue 48).

    python docs/research/probes/batch_probe.py [--steps 40]

Plays the first steps of a hangrcom Setting I test episode, keeps every agent's inputs to the
frozen perception model, then times them as three batches of one per step against one batch of
three (one thread, as the team runs). Then the reason records would change: the last bits of a
torch CPU linear layer's row for batches of 1 to 8 rows. Last, the decision's LSTM steps: torch
runs them through oneDNN (its default on the CPU), which reorders the weights on every call;
its native kernel is faster at a batch of one but gives other bits; and whether that shows in
an episode: the team's steps in alternating blocks, the LSTMs on oneDNN and on the native
kernel (``--blocks``; the native blocks play other bits, so only their time is read).
Nothing is written.
"""

from __future__ import annotations

import argparse
import os
import time

import torch

from maniskill_tidy.eval.episode import Execution
from maniskill_tidy.eval.runner import RunConfig, make_env, select
from maniskill_tidy.models.perception import PerceptionModel
from maniskill_tidy.policies import make_team


def captured_inputs(steps: int, dataset: str) -> tuple[torch.nn.Module, PerceptionModel, list]:
    calls: list[tuple] = []
    step_features = PerceptionModel.step_features

    def keep(self, *inputs):
        calls.append(inputs)
        return step_features(self, *inputs)

    PerceptionModel.step_features = keep
    env, team = make_env(RunConfig("hangrcom", "I", "test", dataset, 1)), make_team("hangrcom")
    i = select([e.start for e in env.unwrapped.episodes.episodes], 1)[0]
    obs, info = env.reset(seed=i, options={"episode": i})
    execution = Execution(team, env.unwrapped, i)
    for _ in range(steps):
        obs, _, _, _, info = env.step(execution.step(obs, info))
    env.close()
    PerceptionModel.step_features = step_features
    return (*next(iter(team._loaded.values())), calls)


def batched(group: list[tuple]) -> tuple:
    """One batch of a step's frames; detections stay flat, their row naming their frame."""
    rows = torch.cat([torch.full((len(a[4]),), k, dtype=torch.long) for k, a in enumerate(group)])
    joined = [torch.cat([a[j] for a in group]) for j in range(7)]
    joined[3] = rows
    return tuple(joined)


def main() -> None:
    # the agents think in this process, where the measuring wrappers are
    os.environ["TIDY_AGENT_PROCESSES"] = "0"
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--blocks", type=int, default=8, help="alternating blocks of 20 team steps")
    args = p.parse_args()
    torch.set_num_threads(1)
    decision, model, calls = captured_inputs(args.steps, args.dataset)
    steps = [calls[j : j + 3] for j in range(0, len(calls) - 2, 3)]
    batches = [batched(g) for g in steps]
    with torch.inference_mode():
        for _ in range(2):  # the second round is reported (caches warm)
            start = time.perf_counter()
            for group in steps:
                for inputs in group:
                    model.step_features(*inputs)
            one = (time.perf_counter() - start) / len(steps)
            start = time.perf_counter()
            for inputs in batches:
                model.step_features(*inputs)
            many = (time.perf_counter() - start) / len(steps)
    print(f"perception per step, 3 agents: 3 batches of one {1e3 * one:.2f} ms, "
          f"one batch of three {1e3 * many:.2f} ms")  # fmt: skip
    torch.manual_seed(0)
    linear, x = torch.nn.Linear(2048, 256), torch.randn(8, 2048)
    with torch.inference_mode():
        alone = linear(x[:1])[0]
        same = [torch.equal(linear(x[:m])[0], alone) for m in range(1, 9)]
        other = x.clone()
        other[1:] = torch.randn(7, 2048)
        content = torch.equal(linear(other)[0], linear(x)[0])
    print("row 0 of a linear layer equals its batch-of-one bits for batches of 1..8:", same)
    print("row 0 independent of the other rows' values (batch of 8):", content)
    lstm_steps(decision.agents[0])
    episode_lstm(args.dataset, args.blocks)


def lstm_steps(agent: torch.nn.Module, steps: int = 200) -> None:
    """Each of one agent's LSTMs (F_s, F_a, F_g) stepped as the team steps it, oneDNN against
    torch's native kernel: milliseconds per step and whether the outputs are the same bits."""
    torch.manual_seed(0)
    for name, lstm in [("F_s", agent.state.lstm), ("F_a", agent.subtask.lstm),
                       ("F_g", agent.subgoal.lstm)]:  # fmt: skip
        xs = torch.randn(steps, 1, 1, lstm.input_size)

        def run(lstm=lstm, xs=xs) -> tuple[torch.Tensor, float]:
            state, out = None, []
            start = time.perf_counter()
            for x in xs:
                y, state = lstm(x, state)
                out.append(y)
            return torch.stack(out), 1e3 * (time.perf_counter() - start) / len(xs)

        with torch.inference_mode():
            run()
            onednn, t_onednn = run()
            with torch.backends.mkldnn.flags(enabled=False):
                run()
                native, t_native = run()
        print(f"{name} LSTM ({lstm.input_size} -> {lstm.hidden_size}) per step: oneDNN "
              f"{t_onednn:.3f} ms, native {t_native:.3f} ms, same bits: "
              f"{torch.equal(onednn, native)}")  # fmt: skip


def episode_lstm(dataset: str, blocks: int, size: int = 20) -> None:
    """A hangrcom episode's team steps, blocks of ``size`` in turns with every LSTM on oneDNN
    and on torch's native kernel (one thread, as the team runs): ms per team step of each."""
    native = {"on": False}
    forward = torch.nn.LSTM.forward

    def switched(self, *a, **k):
        if not native["on"]:
            return forward(self, *a, **k)
        with torch.backends.mkldnn.flags(enabled=False):
            return forward(self, *a, **k)

    torch.nn.LSTM.forward = switched
    env, team = make_env(RunConfig("hangrcom", "I", "test", dataset, 1)), make_team("hangrcom")
    i = select([e.start for e in env.unwrapped.episodes.episodes], 1)[0]
    obs, info = env.reset(seed=i, options={"episode": i})
    execution = Execution(team, env.unwrapped, i)
    spent = {False: [], True: []}
    for block in range(blocks + 1):  # the first block warms up and is not counted
        native["on"] = block % 2 == 0
        for _ in range(size):
            start = time.perf_counter()
            actions = execution.step(obs, info)
            if block:
                spent[native["on"]].append(time.perf_counter() - start)
            obs, _, terminated, truncated, info = env.step(actions)
            if terminated or truncated:
                obs, info = env.reset(seed=i, options={"episode": i})
                execution = Execution(team, env.unwrapped, i)
    env.close()
    torch.nn.LSTM.forward = forward
    ms = {k: 1e3 * sum(v) / max(len(v), 1) for k, v in spent.items()}
    print(f"in an episode, per team step ({blocks} blocks of {size} in turns): LSTMs on oneDNN "
          f"{ms[False]:.2f} ms, native {ms[True]:.2f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
