"""Which objects a pixels team loses that the same team on ground truth places: plays the chosen
episodes twice, first on the renderer's segmentation and object ids, then through the pixels
pipeline (``--labels renderer`` for a perfect segmenter), and prints each object placed only
by the first with how far the pixels team's memory took it (``pixels_unpicked.py``'s flags and
PickUps), each placed only by the second, and the lost objects' fates in all.

    .venv/bin/python docs/research/probes/pixels_vs_truth.py --policy memory \\
        --dataset data/tidy120 --episodes 36 --labels renderer
"""

from __future__ import annotations

from collections import Counter

import pixels_probe
import pixels_unpicked


class FinalInfo:
    """An episode observer keeping the last step's info (its ``reasonable``: objects placed)."""

    def start(self, env, team, channel) -> None:
        self.info: dict = {}

    def log_step(self, t, obs, actions, info, channel, labels) -> None:
        self.info = info


def main() -> None:
    args = pixels_probe.arguments(__doc__, "memory", 36)
    pixels = (args.segmentation, args.labels)
    args.segmentation, args.labels = "ground-truth", "segmenter"
    truth = {r.episode: set(log.info.get("reasonable", []))
             for r, log in pixels_probe.played(args, FinalInfo)}  # fmt: skip
    args.segmentation, args.labels = pixels
    lost: Counter = Counter()
    gained = 0
    for record, log in pixels_probe.played(args, pixels_unpicked.Unpicked):
        placed_by_truth = truth[record.episode]
        for o, oid in zip(log.result()["objects"], log.misplaced, strict=True):
            if oid in placed_by_truth and o["fate"] != "placed":
                lost[o["fate"]] += 1
                print(f"{record.episode} {oid}: {o['fate']}; {sorted(log.flags[oid])} "
                      f"pickups {dict(log.pickups[oid])}")  # fmt: skip
            elif oid not in placed_by_truth and o["fate"] == "placed":
                gained += 1
                print(f"{record.episode} {oid}: placed here, not on ground truth")
    print(f"placed on ground truth, not here: {sum(lost.values())} {dict(lost)}")
    print(f"placed here, not on ground truth: {gained}")


if __name__ == "__main__":
    main()
