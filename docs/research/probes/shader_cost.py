"""Time per picture of one agent camera with SAPIEN's minimal pack and with v1's (issue 48).

    python docs/research/probes/shader_cost.py [--env HeteroTidy-v1] [--frames 40] [--pack DIR ...]

Cameras on agent 0's mount, with the agent camera's parameters: SAPIEN's "minimal" pack,
``sim/shaders/no_ibl`` (v1's, the minimal pack without image-based light) and any ``--pack``
directories. They take turns on the same frames while the team turns and moves; each prints
its milliseconds per picture (take, then read colour and position-segmentation back) and
whether every pixel equals the minimal pack's. In v2, whose environment map lights the scene,
no_ibl's pixels differ, which is why only v1 uses it. Nothing is written.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import sapien

from maniskill_tidy.eval.runner import RunConfig, make_env
from maniskill_tidy.sim import SHADERS, brdf_lut


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="HeteroTidy-v1")
    p.add_argument("--dataset", default="data/tidy120")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--pack", action="append", default=[], help="another shader pack directory")
    args = p.parse_args()

    env = make_env(RunConfig("heuristic-none", "I", "test", args.dataset, 1, env=args.env))
    u = env.unwrapped
    try:
        env.reset(seed=3, options={"episode": 3})
        own = u._agent_camera(u.agent_names[0])
        packs = {
            "minimal": str(Path(sapien.__file__).parent / "vulkan_shader" / "minimal"),
            "no_ibl": str(SHADERS / "no_ibl"),
        } | {Path(d).name: d for d in args.pack}
        cams = {}
        for label, pack in packs.items():
            cam = sapien.render.RenderCameraComponent(own.width, own.height, pack)
            cam.set_fovy(own.fovy, compute_x=True)
            cam.near, cam.far = own.near, own.far
            u.robots[0].add_component(cam)
            cams[label] = cam
        if u.backend.render_device.is_cpu():
            brdf_lut.lend(cams.values())
        rng = np.random.default_rng(0)
        spent = dict.fromkeys(cams, 0.0)
        same = dict.fromkeys(cams, True)
        for k in range(args.frames + 3):  # 3 frames to warm up
            if k % 4 == 0:
                u.step({n: int(rng.integers(0, 7)) for n in u.agent_names})
            u.scene.update_render(update_sensors=True, update_human_render_cameras=False)
            ref = None
            for label, cam in cams.items():
                cam.set_local_pose(own.get_local_pose())
                start = time.perf_counter()
                cam.take_picture()
                pictures = (cam.get_picture("Color"), cam.get_picture("PositionSegmentation"))
                if k >= 3:
                    spent[label] += time.perf_counter() - start
                ref = ref or pictures
                same[label] &= all(np.array_equal(a, b) for a, b in zip(ref, pictures, strict=True))
    finally:
        env.close()
    print(f"{args.env}, {args.frames} frames of agent 0's camera ({own.width} x {own.height})")
    for label in cams:
        print(f"{label:>10}: {1e3 * spent[label] / args.frames:6.2f} ms per picture, "
              f"{'the same pixels' if same[label] else 'OTHER PIXELS'} as minimal")  # fmt: skip


if __name__ == "__main__":
    main()
