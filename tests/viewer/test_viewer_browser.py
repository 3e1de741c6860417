"""Issue 29's acceptance: ``ambulo demo --viewer web`` opened in headless Chromium (Debian's
``chromium``, driven by Playwright, WebGL through SwiftShader) draws the humanoid and the Jetbot
where the simulation says they are, and a command sent from the page moves the humanoid.

Where a body is drawn: with the simulation paused from the page, the page's read-out gives every
robot's root position; the page's camera is the demo's viewport camera (``from_mjv_camera``), so
``project_w`` says where on the canvas each must appear. Screenshots with and without the robot
(hidden from the page's "Bodies" panel) differ exactly where it is drawn; the projected point
must lie in that difference. Every wait is on a condition (the page's text), none on a sleep,
with generous limits: a loaded 2-core machine renders WebGL in software slowly.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from ports import free_port

playwright_api = pytest.importorskip("playwright.sync_api")
pytest.importorskip("viser")
CHROMIUM = shutil.which("chromium")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/setup.sh)")]

WAIT_MS = 300_000
"""Limit of each wait on the page (a condition, not a sleep): software WebGL on a busy machine."""
VIEWPORT = {"width": 1100, "height": 560}
CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--use-gl=angle", "--no-sandbox",
                 "--disable-dev-shm-usage"]
POSITION = r"`{name}` \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) m"
HUMANOID, JETBOT = "/World/Humanoid/pelvis", "/World/Jetbot/chassis"



def page_text(page) -> str:
    return page.evaluate("document.body.innerText")


def position(page, body: str) -> np.ndarray:
    match = re.search(POSITION.format(name=re.escape(body)).replace("`", ""), page_text(page))
    assert match, f"no read-out of {body} on the page"
    return np.array([float(v) for v in match.groups()])


def sim_time(page) -> float:
    return float(re.search(r"t = (-?[\d.]+) s", page_text(page)).group(1))


def wait_text(page, js_condition: str) -> None:
    page.wait_for_function(f"() => {{ const t = document.body.innerText; return {js_condition}; }}",
                           timeout=WAIT_MS)


def wait_sim_time(page, at_least_s: float) -> None:
    wait_text(page, f"(m => m && parseFloat(m[1]) >= {at_least_s})(t.match(/t = (-?[\\d.]+) s/))")


def canvas_image(page) -> tuple[np.ndarray, dict]:
    """The 3-D canvas as an (H, W, 3) uint8 image and its box on the page (CSS px)."""
    from PIL import Image

    box = page.evaluate("(() => { const r = document.querySelector('canvas').getBoundingClientRect(); "
                        "return {x: r.x, y: r.y, width: r.width, height: r.height}; })()")
    png = page.screenshot(clip=box, timeout=WAIT_MS, animations="disabled")
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")), box


def differs(a: np.ndarray, b: np.ndarray, width_px: int) -> np.ndarray:
    """Where two canvas images differ in the scene (left of ``width_px``: the panel floats over the rest)."""
    mask = np.abs(a.astype(int) - b.astype(int)).sum(axis=2) > 30
    mask[:, width_px:] = False
    return mask


def settled_canvas(page, width_px: int, unlike: np.ndarray) -> np.ndarray:
    """The canvas once a change the page was asked for has been drawn (a toggle travels to the server
    and back before the page redraws): two screenshots alike, and unlike ``unlike`` in the scene."""
    deadline = time.monotonic() + WAIT_MS / 1000
    previous = None
    while True:
        image, _ = canvas_image(page)
        if (previous is not None and not differs(image, previous, width_px).any()
                and differs(image, unlike, width_px).any()):
            return image
        assert time.monotonic() < deadline, "the canvas did not change as the page asked"
        previous = image


def set_shown(page, bodies: dict[str, bool]) -> None:
    """Tick or clear the page's "show <body>" boxes."""
    for body, shown in bodies.items():
        box = page.get_by_label(f"show {body}")
        if shown:
            box.check(timeout=WAIT_MS)
        else:
            box.uncheck(timeout=WAIT_MS)


def save(name: str, image: np.ndarray) -> None:
    """With AMBULO_VIEWER_TEST_IMAGES=<folder>, keep the screenshots for a person to look at."""
    folder = os.environ.get("AMBULO_VIEWER_TEST_IMAGES")
    if folder:
        from PIL import Image

        Image.fromarray(image).save(os.path.join(folder, name))


def near_mask(mask: np.ndarray, xy: np.ndarray, radius_px: int) -> bool:
    x, y = int(round(xy[0])), int(round(xy[1]))
    h, w = mask.shape
    window = mask[max(0, y - radius_px):min(h, y + radius_px + 1), max(0, x - radius_px):min(w, x + radius_px + 1)]
    return bool(window.any())


@pytest.fixture
def demo():
    port = free_port()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "ambulo", "demo", "--viewer", "web", "--viewer-port", str(port),
                             "--seconds", "3600", "--no-video", "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    url = None
    for line in proc.stdout:
        found = re.search(r"ambulo viewer: (http://127\.0\.0\.1:\d+)", line)
        if found:
            url = found.group(1)
            break
    assert url is not None, "ambulo demo --viewer web printed no viewer URL"
    yield proc, url
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def test_demo_page_draws_robots_where_simulated_and_teleoperates(demo):
    from ambulo.demo import build_demo_world
    from ambulo.sim import World
    from ambulo.viewer import from_mjv_camera, project_w

    proc, url = demo
    # the camera the page opens with: the demo's viewport camera at the model's field of view
    world, _, _ = build_demo_world()
    world.reset()
    camera = from_mjv_camera(world.viewport_camera, float(world.model.vis.global_.fovy))
    World.clear_instance()

    with playwright_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(url, timeout=WAIT_MS)
        wait_text(page, f"t.includes('{HUMANOID}') && t.includes('{JETBOT}')")

        # pause from the page; the read-out then comes from the held simulation
        page.get_by_role("button", name="Pause").click(timeout=WAIT_MS)
        wait_text(page, "t.includes('paused')")
        humanoid_w, jetbot_w = position(page, HUMANOID), position(page, JETBOT)
        assert humanoid_w[2] > 0.7, "the humanoid should stand while the demo walks it"

        shown, box = canvas_image(page)
        scale = shown.shape[1] / box["width"]  # device pixels per CSS pixel
        panel_x = page.get_by_role("button", name="Resume").bounding_box()["x"] - 20 - box["x"]
        scene_width_px = int(panel_x * scale)
        pixels = project_w(np.stack([humanoid_w, jetbot_w]), camera, int(box["width"]), int(box["height"])) * scale
        save("shown.png", shown)
        # each robot alone against the empty scene: a crate or the other robot in front cannot hide it
        roots = [m.group(1) for m in re.finditer(r"show (\S+)", page_text(page))]
        set_shown(page, dict.fromkeys(roots, False))
        empty = settled_canvas(page, scene_width_px, shown)
        for body, xy in zip((HUMANOID, JETBOT), pixels):
            assert 0 <= xy[0] < scene_width_px and 0 <= xy[1] < shown.shape[0], f"{body} is off the visible scene"
            set_shown(page, {body: True})
            alone = settled_canvas(page, scene_width_px, empty)  # fails if showing it draws nothing
            set_shown(page, {body: False})
            settled_canvas(page, scene_width_px, alone)  # hidden again before the next one shows
            save(f"alone_{body.split('/')[2]}.png", alone)
            mask = differs(alone, empty, scene_width_px)
            # the root body's origin is inside its drawn shape (pelvis capsule, chassis box): within a few pixels
            assert near_mask(mask, xy, radius_px=int(6 * scale)), \
                f"{body} at {xy} px is not where the page draws it (drawn pixels span " \
                f"x {np.nonzero(mask)[1].min()}-{np.nonzero(mask)[1].max()}, " \
                f"y {np.nonzero(mask)[0].min()}-{np.nonzero(mask)[0].max()})"
            ys, xs = np.nonzero(mask)
            assert abs(np.median(xs) - xy[0]) < 0.5 * (xs.max() - xs.min()) + 4 * scale

        set_shown(page, dict.fromkeys(roots, True))

        # teleoperation from the page's keys: X stops the humanoid, W four times walks it at 0.4 m/s
        page.get_by_role("button", name="Resume").click(timeout=WAIT_MS)
        wait_text(page, "t.includes('running')")
        page.locator("body").press("x")
        t0 = sim_time(page)
        wait_sim_time(page, t0 + 2.0)
        stood_at = position(page, HUMANOID)
        t1 = sim_time(page)
        wait_sim_time(page, t1 + 2.0)
        stood_m = np.linalg.norm(position(page, HUMANOID)[:2] - stood_at[:2])
        for _ in range(4):
            page.locator("body").press("w")
        walk_from, t2 = position(page, HUMANOID), sim_time(page)
        wait_sim_time(page, t2 + 4.0)
        walked_m = np.linalg.norm(position(page, HUMANOID)[:2] - walk_from[:2])
        browser.close()

    assert stood_m < 0.25, f"commanded to stop from the page, the humanoid still moved {stood_m:.2f} m in 2 s"
    assert walked_m > 0.6, f"commanded 0.4 m/s from the page, the humanoid moved only {walked_m:.2f} m in 4 s"

    # Ctrl-C ends the demo and its server
    port = int(url.rsplit(":", 1)[1])
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=120) == 130
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0, "the viewer's port is still open after Ctrl-C"
