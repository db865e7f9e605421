"""Nothing an agent receives rebuilds its task: no generator seed, opaque house and episode
ids, object ids that name no origin, and a split whose seed no file records."""

from __future__ import annotations

import gzip
import json

import pytest

from maniskill_tidy.policies.base import PublicInfo
from maniskill_tidy.tasks.dataset import SECRET_SEED_VARIABLE, generate_dataset, load_dataset
from tests.test_cli_errors import cli, one_line_error


class SpyTeam:
    """Records the public information each agent is made with (a camera-only team)."""

    seen: list = []

    @classmethod
    def make(cls):
        from maniskill_tidy.policies import make_team

        team = make_team("heuristic-none")
        inner = team.make_agent

        def make_agent(name, public, outbox):
            cls.seen.append(public)
            return inner(name, public, outbox)

        team.make_agent = make_agent
        return team


def test_agents_receive_no_seed_and_opaque_ids():
    from maniskill_tidy.envs.hetero_tidy import HeteroTidyEnv
    from maniskill_tidy.eval.episode import Execution

    env = HeteroTidyEnv(setting="I", split="test", obs_mode="state")
    try:
        publics = []
        for episode in (0, 0, 7):
            env.reset(seed=episode, options={"episode": episode})
            SpyTeam.seen = []
            Execution(SpyTeam.make(), env, episode)
            assert len(SpyTeam.seen) == 3
            public = SpyTeam.seen[0]
            house, ep = env.house, env.episode
            assert public.house.seed is None and house.seed is not None
            assert public.house.objects == [] and house.objects
            for text in (public.house.id, public.episode_id):
                assert house.id not in text and ep.id not in text
                assert "task" not in text and "start" not in text
                assert not any(part in text for part in house.id.split("_") if part.isdigit())
            # the same house and episode keep their names, as records need
            publics.append((public.house.id, public.episode_id))
    finally:
        env.close()
    assert publics[0] == publics[1] and publics[0][1] != publics[2][1]


def test_the_public_info_holds_nothing_of_the_generator():
    """Every field of a camera-only agent's public information, by name: a new one must be
    argued for here."""
    import dataclasses

    assert {f.name for f in dataclasses.fields(PublicInfo)} == {
        "house", "agents", "capabilities", "episode_id", "seed", "instances",
        "oracle_misplaced",
    }  # fmt: skip


def test_imported_objects_carry_no_room_in_their_ids():
    from maniskill_tidy.houses.procthor import read_procthor_houses
    from tests.test_procthor import SAMPLE

    objects = [o for h in read_procthor_houses(SAMPLE) for o in h.objects]
    assert len(objects) > 50
    for o in objects:
        kind, _, n = o.id.rpartition("_")
        assert kind == o.type and n.isdigit() and "|" not in o.id, o.id


def _files(folder):
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            data = p.read_bytes()
            yield p, gzip.decompress(data) if p.suffix == ".gz" else data


def test_a_secret_split_records_no_seed(tmp_path, monkeypatch):
    seed = 2**61 + 12345
    generate_dataset(tmp_path / "secret", 6, seed, (4, 1, 1), progress=False, secret=True)
    generate_dataset(tmp_path / "open", 6, seed, (4, 1, 1), progress=False)
    for p, data in _files(tmp_path / "secret"):
        assert str(seed).encode() not in data, p
    assert str(seed).encode() in (tmp_path / "open" / "manifest.json").read_bytes()
    manifest = json.loads((tmp_path / "secret" / "manifest.json").read_text())
    assert manifest["seed"] == "secret"
    secret = load_dataset(tmp_path / "secret", "test")
    open_ = load_dataset(tmp_path / "open", "test")
    for hid, house in secret.houses.items():  # the same houses and tasks, without the seed
        assert house.seed is None and open_.houses[hid].seed == seed
        assert house.rooms == open_.houses[hid].rooms
    assert [t.to_dict() for t in secret.tasks] == [t.to_dict() for t in open_.tasks]
    with pytest.raises(Exception, match="other arguments"):  # resumed only with the same secret
        generate_dataset(tmp_path / "secret", 6, seed + 1, (4, 1, 1), progress=False, secret=True)

    # the command line reads it from a file or the environment, never from an argument
    (tmp_path / "seed.txt").write_text(f"{seed}\n")
    p = cli("generate", "--houses", "6", "--split", "4,1,1", "--out", str(tmp_path / "cli"),
            "--secret-seed-file", str(tmp_path / "seed.txt"))  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "cli" / "manifest.json").read_bytes() == (
        tmp_path / "secret" / "manifest.json"
    ).read_bytes()
    p = cli("generate", "--houses", "6", "--out", str(tmp_path / "env"), "--secret-seed",
            env={SECRET_SEED_VARIABLE: str(seed)})  # fmt: skip
    assert p.returncode == 0, p.stderr


@pytest.mark.parametrize(
    "text, words",
    [("12", ["2**32", "secrets.randbits(64)"]), ("seed", ["expected an integer seed"])],
)
def test_a_weak_or_malformed_secret_is_refused(tmp_path, text, words):
    (tmp_path / "seed.txt").write_text(text)
    p = cli("generate", "--houses", "6", "--out", str(tmp_path / "d"),
            "--secret-seed-file", str(tmp_path / "seed.txt"))  # fmt: skip
    one_line_error(p, *words)
    assert not (tmp_path / "d").exists()
    p = cli("generate", "--houses", "6", "--out", str(tmp_path / "d"), "--secret-seed",
            env={SECRET_SEED_VARIABLE: ""})  # fmt: skip
    one_line_error(p, SECRET_SEED_VARIABLE, "not set")
