"""Make docs/images/viewer_grid.png and viewer_overlays.png: the web viewer in headless Chromium
(Debian's ``chromium`` through Playwright, as tests/viewer/test_viewer_browser.py drives it).

    .venv/bin/python tests/viewer/viewer_screenshots.py [grid|overlays ...] [--out docs/images]

- grid: 9 humanoid-walk envs walked by the shipped policy, drawn as a 3 x 3 grid (``serve(env, grid=9)``).
- overlays: one navigation episode (apartment 3, oracle mode) with the navigator feeding the
  viewer (``Navigator.add_observer(viewer.navigator_observer)``: map, route, footsteps, walked
  path), contact forces, CoM / ZMP / capture point and the head camera switched on.

Not a test (pytest collects ``test_*.py`` only): it writes files for people to look at.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--use-gl=angle", "--no-sandbox",
                 "--disable-dev-shm-usage"]
VIEWPORT = {"width": 1280, "height": 720}
WAIT_MS = 300_000


def look(viewer, eye_w, target_w) -> None:
    """Put every page's camera at ``eye_w`` looking at ``target_w`` (follow off)."""
    viewer.page.panel.follow.value = False
    for client in viewer.page.server.get_clients().values():
        with client.atomic():
            client.camera.up_direction = (0.0, 0.0, 1.0)
            client.camera.position = tuple(eye_w)
            client.camera.look_at = tuple(target_w)


def screenshot(viewer, path: Path, setup, settle_s: float = 8.0, expand: str | None = None) -> None:
    """Open the page, let ``setup(viewer)`` place the camera, wait ``settle_s`` for software WebGL, save."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=shutil.which("chromium"), headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(viewer.url, timeout=WAIT_MS)
        page.wait_for_function("() => document.body.innerText.includes('frames sent')", timeout=WAIT_MS)
        setup(viewer)
        time.sleep(2.0)
        setup(viewer)  # again: the viewer's own camera placement on connect may land after the first
        time.sleep(settle_s)
        close = page.locator(".mantine-Notification-closeButton")  # the "software WebGL" notice
        for i in range(close.count()):
            close.nth(i).click(timeout=WAIT_MS)
        if expand is not None:  # open a folder of the panel
            page.get_by_text(expand, exact=True).click(timeout=WAIT_MS)
        time.sleep(4.0)
        page.screenshot(path=str(path), timeout=WAIT_MS)
        browser.close()
    print(f"wrote {path}")


def grid(out: Path) -> None:
    import torch

    import ambulo.viewer
    from ambulo import envs
    from ambulo.policies.shipped import load_policy

    env = envs.make("humanoid-walk", num_envs=9, seed=0)
    policy = load_policy()
    viewer = ambulo.viewer.serve(env, port=8097, grid=9, process=False)
    obs = env.get_observations()
    for _ in range(150):  # 3 s of walking at 50 Hz
        with torch.inference_mode():
            obs, *_ = env.step(policy(obs))
    spacing = viewer.page.grid.spacing_m
    centre = np.array([spacing, spacing, 0.5])
    try:
        screenshot(viewer, out / "viewer_grid.png",
                   lambda v: look(v, centre + [-3.2 * spacing, -2.2 * spacing, 2.6 * spacing], centre))
    finally:
        viewer.close()


def overlays(out: Path) -> None:
    import ambulo.viewer
    from ambulo.navigation import Navigator, NavWorld
    from ambulo.navigation.benchmark import EpisodeSpec, episode_cfg, make_walker
    from ambulo.robots import humanoid
    from ambulo.scenes.apartment import apartment

    spec = EpisodeSpec(3, 0, "oracle", "policy", False)
    cfg = episode_cfg(spec)
    world_cfg = type(cfg.world)(**{**cfg.world.__dict__, "record_gyro": False})
    apt = apartment(3)
    ep = apt.sample_start_goal(0, cfg.min_geodesic_m, cfg.max_geodesic_m, humanoid.BODY_RADIUS_M)
    world = NavWorld.from_apartment(apt, tuple(ep.start_pose), world_cfg)
    viewer = ambulo.viewer.serve(world, port=8098, process=False)
    viewer.controls.speed = None
    for box in (viewer.page.overlays.contacts, viewer.page.overlays.balance, viewer.page.overlays.camera):
        box.value = True
    nav = Navigator(world, cfg.navigator, walker=make_walker("policy"))
    nav.add_observer(viewer.navigator_observer, images=False)
    nav.set_goal(ep.goal_xy_m)
    try:
        nav.run(max_time_s=6.0)
        pose = world.true_pose()
        robot = np.array([pose[0], pose[1], 0.6])
        goal = np.array([*ep.goal_xy_m, 0.0])
        target = 0.5 * (robot + goal)
        away = robot - goal
        away[:2] /= max(np.linalg.norm(away[:2]), 1e-6)
        screenshot(viewer, out / "viewer_overlays.png",
                   lambda v: look(v, robot + [1.3 * away[0], 1.3 * away[1], 3.6], 0.7 * robot + 0.3 * target),
                   expand="Overlays")
    finally:
        viewer.close()
        world.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("which", nargs="*", default=["grid", "overlays"], choices=["grid", "overlays"])
    parser.add_argument("--out", default="docs/images")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for which in args.which:
        {"grid": grid, "overlays": overlays}[which](out)


if __name__ == "__main__":
    main()
