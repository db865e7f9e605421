"""Agents that think in processes of their own (issue 48).

A team's agents touch nothing but their own state (``policies/base.py``), yet on threads they
barely think side by side: most of an agent's step is small torch and numpy calls between which
it holds Python's lock. Here each agent of a team lives in a process of its own (a *host*,
kept for the next episodes): every phase of a step (observe, each communication round, act)
is posted to all the agents' hosts before any answer is read, so the agents think at once on
as many cores as there are; a step between sub-goal steps, on which nobody sends, is one call
(:meth:`Agent.quiet_step`). A host answers with what its agent returned and the messages it
sent, which the runner puts on the channel in the order the agents would have sent them in
this process. The same code on the same inputs, torch on one thread in both: the same records
(``tests/test_teams.py`` plays a team both ways and compares every step).

``TIDY_AGENT_PROCESSES=1`` turns it on for any team whose agents allow it
(:attr:`Team.threadsafe_agents`, made by ``make_team``, which the host repeats), ``0`` off;
unset, it is on for teams whose agents think long enough to pay for the messages
(:attr:`Team.agent_processes`: the learned ones) where the runner's process has two cores or
more to itself (``agent_threads``: not under ``eval --workers 2`` on two cores). Hosts start
from a fork server that has imported the package once.
"""

from __future__ import annotations

import atexit
import mmap
import multiprocessing
import os
import signal
import sys
import tempfile
import traceback
import types
import uuid
from typing import Any

import numpy as np

from maniskill_tidy.common.parallel import THREAD_KNOBS, agent_processes_knob, agent_threads
from maniskill_tidy.policies.base import Agent, AgentAction, AgentView, Label, PublicInfo
from maniskill_tidy.policies.channel import Message, Outbox

PRELOAD = ["maniskill_tidy.policies", "maniskill_tidy.models.perception"]


def wanted(team: Any, agents: int) -> bool:
    """Whether this team's agents should think in hosts (see the top)."""
    knob = agent_processes_knob()
    if agents < 2 or not getattr(team, "threadsafe_agents", False):
        return False
    if getattr(team, "spec", None) is None:  # not made by make_team: a host cannot repeat it
        return False
    if knob is not None:
        return knob
    return getattr(team, "agent_processes", False) and agent_threads() >= 2


class RecordingOutbox:
    """An agent's outbox in its host: it keeps what the agent sends, for the runner's channel."""

    def __init__(self, sender: str, peers: list[str], has_central: bool) -> None:
        self.sender, self.peers, self.has_central = sender, list(peers), has_central
        self.sent: list[tuple[list[str] | str, np.ndarray, str]] = []

    def send(self, receivers: list[str] | str, vector, kind: str) -> None:
        receivers = receivers if isinstance(receivers, str) else list(receivers)
        self.sent.append((receivers, np.array(vector), kind))

    def take(self) -> list:
        sent, self.sent = self.sent, []
        return sent


def _read_only(value):
    """Arrays arrive writable from a pipe; an agent gets them read-only, as in this process."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    return value


SHARED = 4096  # bytes from which an observation's array goes through the host's shared buffer
ALIGN = 64


class SharedFrames:
    """An observation's images through a file in shared memory instead of the pipe (the runner
    would otherwise pickle three 224 x 224 frames per agent and step). The runner
    writes a step's arrays; the host copies them out before it answers, so the next step's
    write never meets an agent still reading. Once the host has mapped the file its name is
    removed (:meth:`mapped`): a killed run leaves nothing in /dev/shm."""

    def __init__(self) -> None:
        self.path: str | None = None
        self.buffer: mmap.mmap | None = None
        self.linked = False

    def pack(self, obs: dict[str, np.ndarray]) -> tuple[str | None, dict]:
        """The runner's side: (the buffer's path, each key's array or where it lies)."""
        arrays = {k: np.asarray(v) for k, v in obs.items()}
        big = [k for k, a in arrays.items() if a.nbytes >= SHARED]
        size = sum(-(-arrays[k].nbytes // ALIGN) * ALIGN for k in big)
        if big and (self.buffer is None or len(self.buffer) < size):
            self.close()
            folder = "/dev/shm" if os.path.isdir("/dev/shm") else None
            # a name never used before: the host maps each new name once
            fd, self.path = tempfile.mkstemp(prefix=f"tidy-agent-{uuid.uuid4().hex}-", dir=folder)
            os.ftruncate(fd, size)
            self.buffer = mmap.mmap(fd, size)
            self.linked = True
            os.close(fd)
        out, offset = {}, 0
        for k, a in arrays.items():
            if k not in big:
                out[k] = a
                continue
            np.ndarray(a.shape, a.dtype, buffer=self.buffer, offset=offset)[...] = a
            out[k] = ("shared", a.dtype.str, a.shape, offset)
            offset += -(-a.nbytes // ALIGN) * ALIGN
        return self.path, out

    def mapped(self) -> None:
        """The host has mapped the buffer: its name is no longer needed."""
        if self.linked:
            os.unlink(self.path)
            self.linked = False

    def close(self) -> None:
        self.mapped()
        if self.buffer is not None:
            self.buffer.close()
        self.path, self.buffer = None, None


def _unpack(buffers: dict[str, mmap.mmap], path: str | None, packed: dict) -> dict:
    """The host's side of :meth:`SharedFrames.pack`: the observation, its own read-only copy."""
    if path is not None and path not in buffers:
        for old in buffers.values():
            old.close()
        buffers.clear()
        with open(path, "r+b") as f:
            buffers[path] = mmap.mmap(f.fileno(), 0)
    out = {}
    for k, v in packed.items():
        if isinstance(v, tuple) and v[0] == "shared":
            _, dtype, shape, offset = v
            v = np.ndarray(shape, np.dtype(dtype), buffer=buffers[path], offset=offset).copy()
        out[k] = _read_only(v)
    return out


def _serve(conn) -> None:
    """A host's loop: build agents, run their calls, answer with results and sent messages."""
    from maniskill_tidy.policies import make_team

    # Ctrl-C is the runner's to handle (it closes its hosts); a host that took it too would
    # print a traceback of its own from inside its wait
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    teams: dict[str, Any] = {}
    buffers: dict[str, mmap.mmap] = {}
    agent: Agent | None = None
    outbox: RecordingOutbox | None = None
    while True:
        try:
            request = conn.recv()
        except EOFError:  # the runner is gone
            return
        method, args = request
        try:
            if method == "close":
                return
            if method == "make":
                cwd, spec, key, name, public, peers, has_central = args
                os.chdir(cwd)  # a config's path means what it means in the runner
                if key not in teams:  # the runner's team is another (its weights may be too)
                    teams.clear()
                    teams[key] = make_team(spec)
                outbox = RecordingOutbox(name, peers, has_central)
                agent = teams[key].make_agent(name, public, outbox)
                result = agent.decide_every  # the runner plans its quiet steps by it
            elif method == "observe":
                name, step, path, packed, failed = args
                obs = _unpack(buffers, path, packed)
                result = agent.observe(AgentView(name, step, obs, failed))
            elif method == "quiet_step":
                name, step, path, packed, failed, rounds = args
                view = AgentView(name, step, _unpack(buffers, path, packed), failed)
                result = (agent.quiet_step(view, rounds), agent.label(), agent.trace())
            elif method in ("send", "act"):
                r_or_none, inbox = args
                for m in inbox:
                    _read_only(m.vector)
                if method == "send":
                    result = agent.send(r_or_none, inbox)
                else:
                    result = (agent.act(inbox), agent.label(), agent.trace())
            else:
                raise ValueError(f"unknown host call {method!r}")
            conn.send(("ok", result, outbox.take() if outbox is not None else []))
        except BaseException:  # the runner raises it, with this traceback
            conn.send(("error", traceback.format_exc(), []))


class AgentHost:
    """The runner's end of one host process."""

    def __init__(self, context) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child,), daemon=True,
                                       name="agent-host")  # fmt: skip
        self.process.start()
        child.close()
        self.pending: str | None = None
        self.frames = SharedFrames()

    def post(self, method: str, *args) -> None:
        if self.pending is not None:
            raise RuntimeError(f"host busy with {self.pending!r}, asked for {method!r}")
        try:
            self.conn.send((method, args))
        except OSError:  # its end of the pipe is gone
            raise self._died(method) from None
        self.pending = method

    def collect(self) -> tuple[Any, list]:
        method, self.pending = self.pending, None
        try:
            status, result, sent = self.conn.recv()
        except (EOFError, OSError):
            raise self._died(method) from None
        if status == "error":
            raise RuntimeError(f"an agent's host failed during {method!r}:\n{result}")
        return result, sent

    def _died(self, method: str) -> RuntimeError:
        self.process.join(timeout=1)
        return RuntimeError(f"an agent's host process died during {method!r} "
                            f"(exit code {self.process.exitcode})")  # fmt: skip

    def close(self) -> None:
        try:
            self.conn.send(("close", ()))
        except (BrokenPipeError, OSError):
            pass
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
        self.frames.close()


_hosts: list[AgentHost] = []


def hosts(n: int) -> list[AgentHost]:
    """``n`` hosts of this process, started once (from a fork server with the package
    imported, under one thread per library: each host thinks on one core)."""
    dead = [h for h in _hosts if not h.process.is_alive()]
    for h in dead:
        _hosts.remove(h)
    if len(_hosts) < n:
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(PRELOAD)
        saved = {k: os.environ.get(k) for k in THREAD_KNOBS}
        os.environ.update({k: "1" for k in THREAD_KNOBS})
        # multiprocessing would import the runner's main script in the fork server and every
        # host (to unpickle what it defines); a host needs nothing from it, and a script
        # without an ``if __name__ == "__main__"`` guard would run again there
        main = sys.modules["__main__"]
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            while len(_hosts) < n:
                _hosts.append(AgentHost(context))
        finally:
            sys.modules["__main__"] = main
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    return _hosts[:n]


def hosts_cpu_seconds() -> float:
    """CPU seconds the live hosts have used (Linux; 0 elsewhere): a process's own rusage counts
    its children only once they have ended, and hosts live on."""
    total = 0.0
    for h in _hosts:
        try:
            with open(f"/proc/{h.process.pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
    return total


@atexit.register
def close_hosts() -> None:
    while _hosts:
        _hosts.pop().close()


class RemoteAgent(Agent):
    """The runner's handle on an agent that lives in a host. ``observe``, ``send`` and ``act``
    block; the runner posts a phase to every agent first (:meth:`post`, :meth:`collect`)."""

    def __init__(self, host: AgentHost, team: Any, name: str, public: PublicInfo,
                 outbox: Outbox) -> None:  # fmt: skip
        super().__init__(name, public, outbox)
        self.host = host
        self._label: Label | None = None
        self._trace: dict = {}
        self._posted = "make"  # the host builds the agent meanwhile; collect() waits for it
        if not hasattr(team, "host_key"):  # the host makes this team once, not a stale one
            team.host_key = uuid.uuid4().hex
        host.post("make", os.getcwd(), team.spec, team.host_key, name, public, outbox.peers,
                  outbox.has_central)  # fmt: skip

    def post(self, method: str, *args) -> None:
        """Start ``method`` (observe, send, act or quiet_step) in the host."""
        if method in ("observe", "quiet_step"):
            view, *rest = args
            args = (view.name, view.step, *self.host.frames.pack(view.obs), view.failed, *rest)
        elif method == "act":
            args = (None, *args)
        self._posted = method
        self.host.post(method, *args)

    def collect(self) -> Any:
        """The posted call's result, once the messages it sent are on the channel."""
        result, sent = self.host.collect()
        for receivers, vector, kind in sent:
            self.outbox.send(receivers, vector, kind)
        if self._posted == "make":
            self.decide_every = result
        if self._posted in ("observe", "quiet_step"):
            self.host.frames.mapped()
        if self._posted in ("act", "quiet_step"):
            result, self._label, self._trace = result
        return result

    def observe(self, view: AgentView) -> None:
        self.post("observe", view)
        return self.collect()

    def send(self, round: int, inbox: list[Message]) -> None:
        self.post("send", round, inbox)
        return self.collect()

    def act(self, inbox: list[Message]) -> AgentAction:
        self.post("act", inbox)
        return self.collect()

    def quiet_step(self, view: AgentView, rounds: int) -> AgentAction:
        self.post("quiet_step", view, rounds)
        return self.collect()

    def label(self) -> Label | None:
        return self._label

    def trace(self) -> dict:
        return self._trace
