"""The meshcat viewer as a person would use it: one offline page holding the scene, a server that never outlives
the viewer, and a core that never imports meshcat."""

from __future__ import annotations

import base64
import io
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import drawn_map, small_config
from PIL import Image

import uamfleet
from uamfleet.config import Request
from uamfleet.rollout import Trajectory, run_episode
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD, WAITING, StepEvents
from uamfleet.viz.meshcat_view import FleetViewer, map_texture
from uamfleet.viz.strip import StopEvent, onboard_counts, stop_events

ROOT = Path(__file__).resolve().parents[2]

# North-west cell (first line, first character) is below the threshold; everything else is at 0 dB.
NW_BAD = """
#....
.....
.....
.....
.....
"""

E, N, W, S = 0, 4, 8, 12  # headings: 22.5° * k counter-clockwise from east


def scripted_episode() -> tuple[Trajectory, uamfleet.EnvConfig]:
    """Two taxis on a 500 m drawn map. Taxi 0 serves passenger 1 (released at 0) and then passenger 2 (released at
    step 2); taxi 1 shuttles north-south in the far corner and serves nobody."""
    cfg = small_config(
        NW_BAD,
        starts_m=((150.0, 150.0), (450.0, 50.0)),
        requests=(Request(0, (350.0, 150.0), (350.0, 350.0)), Request(2, (150.0, 350.0), (450.0, 450.0))),
    )
    script = [E, E, N, N, W, W, E, E, E, N]

    def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
        t = len(calls)
        calls.append(t)
        return np.array([[script[min(t, len(script) - 1)], N if t % 2 == 0 else S]])

    calls: list[int] = []
    traj = run_episode(uamfleet.VectorEnv(cfg, num_envs=1, autoreset=False), policy, seed=0)
    return traj, cfg


@pytest.fixture(scope="module")
def episode() -> tuple[Trajectory, uamfleet.EnvConfig]:
    return scripted_episode()


@pytest.fixture(scope="module")
def page(episode: tuple[Trajectory, uamfleet.EnvConfig], tmp_path_factory: pytest.TempPathFactory) -> str:
    traj, cfg = episode
    out = tmp_path_factory.mktemp("page") / "scene.html"
    with FleetViewer(cfg.radio, cfg.sinr_min_db, title="scripted <test> episode") as viewer:
        viewer.show_trajectory(traj)
        assert viewer.server_process is None  # open_server=False starts nothing
        written = viewer.export_html(out)
    assert written == out
    return out.read_text(encoding="utf-8")


def commands_of(html: str) -> list[dict]:
    import umsgpack

    block = re.search(r"var uamfleetCommands = \[(.*?)\];", html, re.S)
    assert block is not None, "the page must carry its scene as a command list"
    return [umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'"([A-Za-z0-9+/=]+)"', block.group(1))]


def test_the_episode_is_the_one_scripted(episode: tuple[Trajectory, uamfleet.EnvConfig]) -> None:
    traj, _ = episode
    assert traj.terminated, "both passengers must be delivered for the visibility checks below to mean anything"
    assert traj.stacked("pickups")[:, 1].sum() == 0  # taxi 1 serves nobody


def test_page_is_self_contained(page: str) -> None:
    tags = re.findall(r"<(?:script|link|img|iframe)\b[^>]*>", page, re.I)
    assert tags, "the page has its scripts inline"
    for tag in tags:
        assert not re.search(r"\b(?:src|href)\s*=", tag, re.I), f"external resource in {tag!r}"
    assert not re.search(r"""(?:src|href)\s*=\s*["']?(?:https?:)?//""", page, re.I)
    assert "@import" not in page
    import meshcat

    main_js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
    assert main_js[:2000] in page and main_js[-2000:] in page  # meshcat's viewer, inline
    assert "new MeshCat.Viewer(" in page
    assert "<title>scripted &lt;test&gt; episode</title>" in page  # the title is escaped


def test_page_holds_the_scene(page: str, episode: tuple[Trajectory, uamfleet.EnvConfig]) -> None:
    traj, _ = episode
    manifest = json.loads(re.search(r'id="uamfleet-scene">(.*?)</script>', page, re.S).group(1))  # type: ignore[union-attr]
    paths = set(manifest["paths"])
    for expected in (
        "/meshcat/ground/slab",
        "/meshcat/radio_map",
        "/meshcat/legend",
        "/meshcat/taxis/taxi_0/body",
        "/meshcat/taxis/taxi_1/pods/pod_2",
        "/meshcat/passengers/S1/marker",
        "/meshcat/passengers/D2/served",
        "/meshcat/passengers/S2/label",
        "/meshcat/paths/taxi_0/line",
    ):
        assert expected in paths, expected
    assert not any(p.startswith("/meshcat/passengers/S3") for p in paths)  # two requests, two pairs of stops
    assert manifest["frames"] == traj.num_steps + 1
    commands = commands_of(page)
    assert {c["type"] for c in commands} == {"set_object", "set_transform", "set_property", "set_animation"}
    objects = {c["path"]: c["object"] for c in commands if c["type"] == "set_object"}
    assert objects["/meshcat/taxis/taxi_0/body"]["object"]["type"] == "Mesh"
    assert objects["/meshcat/paths/taxi_0/line"]["object"]["type"] == "Line"
    assert objects["/meshcat/legend"]["object"]["type"] == "Sprite"
    texture = objects["/meshcat/radio_map"]["images"][0]["url"]
    assert texture.startswith("data:image/png;base64,")  # the map travels inside the page
    assert commands[-1]["type"] == "set_animation"  # last: its tracks bind to objects that exist by then


def tracks(page: str) -> dict[str, dict[str, list[tuple[float, object]]]]:
    """path -> track name -> [(frame, value)] of the page's animation."""
    animation = commands_of(page)[-1]
    out: dict[str, dict[str, list[tuple[float, object]]]] = {}
    for entry in animation["animations"]:
        for track in entry["clip"]["tracks"]:
            out.setdefault(entry["path"], {})[track["name"]] = [(k["time"], k["value"]) for k in track["keys"]]
    return out


def shown_at(keys: list[tuple[float, object]], frame: int) -> object:
    """A discrete track's value at a frame (the last key at or before it)."""
    return [v for t, v in keys if t <= frame][-1]


def test_animation_follows_the_events(page: str, episode: tuple[Trajectory, uamfleet.EnvConfig]) -> None:
    traj, _ = episode
    anim = tracks(page)
    frames = range(traj.num_steps + 1)
    # Taxis: one position key per step, at the positions flown (scene units: km, map centre at FleetViewer.shift).
    position = anim["/meshcat/taxis/taxi_0"][".position"]
    assert [t for t, _ in position] == list(frames)
    viewer_xy = np.array([v[:2] for _, v in position])
    flown_km = traj.positions_m[0] / 1000.0
    offset = viewer_xy - flown_km
    assert np.allclose(offset, offset[0], atol=1e-5)  # a pure translation of the flown path
    # Passenger 2 appears at its release step (2), not before.
    released = anim["/meshcat/passengers/S2"][".visible"]
    assert [shown_at(released, f) for f in frames] == [f >= 2 for f in frames]
    # Origins turn grey at the pick-up, destinations at the drop-off (steps read off the events by hand).
    picked, dropped = traj.stacked("picked_up"), traj.stacked("dropped_off")  # [T, P]
    for p in range(2):
        pick_step = int(np.argmax(picked[:, p])) + 1  # position index after the boarding step
        drop_step = int(np.argmax(dropped[:, p])) + 1
        assert 0 < pick_step < drop_step
        served_s = anim[f"/meshcat/passengers/S{p + 1}/served"][".visible"]
        marker_d = anim[f"/meshcat/passengers/D{p + 1}/marker"][".visible"]
        assert [shown_at(served_s, f) for f in frames] == [f >= pick_step for f in frames]
        assert [shown_at(marker_d, f) for f in frames] == [f < drop_step for f in frames]
    # Pods: as many lit as passengers on board (boardings minus drop-offs so far).
    on_board = np.concatenate([[0], np.cumsum(traj.stacked("pickups")[:, 0] - traj.stacked("dropoffs")[:, 0])])
    for k in (1, 2):
        pod = anim[f"/meshcat/taxis/taxi_0/pods/pod_{k}"][".visible"]
        assert [shown_at(pod, f) for f in frames] == [bool(on_board[f] >= k) for f in frames]
    assert on_board.max() >= 1
    idle = anim["/meshcat/taxis/taxi_1/pods/pod_1"][".visible"]
    assert not any(v for _, v in idle)


def test_stops_are_attributed_to_the_taxi_that_made_them() -> None:
    """Two taxis board one passenger each in the same step; then passenger 0 is dropped off by taxi 0 while taxi 1
    happens to be nearer to that destination."""

    def events(pos: list[list[float]], picked: list[bool], dropped: list[bool], ups: list[int], downs: list[int]):
        a, p = len(pos), len(picked)
        zeros = np.zeros((1, a))
        return StepEvents(
            prev_pos_m=np.zeros((1, a, 2)), pos_m=np.array([pos], dtype=float), actions=zeros.astype(int),
            moved=zeros.astype(bool), blocked=zeros.astype(bool), first_visit=zeros.astype(bool),
            block_visits=zeros.astype(np.int32), picked_up=np.array([picked]), dropped_off=np.array([dropped]),
            released=np.zeros((1, p), bool), pickups=np.array([ups]), dropoffs=np.array([downs]),
            separation_violation=zeros.astype(bool), segment_min_sinr_db=zeros, all_delivered=np.zeros(1, bool),
            t=np.zeros(1, int), heading_flown=-np.ones((1, a), int), shield_intervened=zeros.astype(bool),
            hovered=zeros.astype(bool),
        )  # fmt: skip

    traj = Trajectory(
        scenario="hand-made", radio_name="none", sinr_min_db=-3.0, step_m=100.0, slot_s=3.0, seats=2,
        start_pos_m=np.array([[0.0, 0.0], [1000.0, 0.0]]), pax_exists=np.array([True, True]),
        release_step=np.array([0, 0]), origin_m=np.array([[50.0, 0.0], [1000.0, 50.0]]),
        destination_m=np.array([[500.0, 500.0], [1500.0, 0.0]]),
        events=[
            events([[0.0, 0.0], [1000.0, 0.0]], [True, True], [False, False], [1, 1], [0, 0]),
            events([[450.0, 500.0], [500.0, 480.0]], [False, False], [True, False], [0, 0], [1, 0]),
        ],
    )  # fmt: skip
    assert stop_events(traj) == [
        StopEvent(1, 0, 0, "pickup"),
        StopEvent(1, 1, 1, "pickup"),
        StopEvent(2, 0, 0, "dropoff"),
    ]
    assert onboard_counts(traj).tolist() == [[0, 1, 0], [0, 1, 1]]


def test_map_texture_is_north_up_with_no_fly_cells_marked() -> None:
    radio = drawn_map(NW_BAD)
    png, stride, extent = map_texture(radio, threshold_db=-3.0)
    assert stride == 1
    assert extent == (0.0, 500.0, 0.0, 500.0)  # cell edges of the 5 x 5 raster of 100 m cells
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(float) / 255
    cell = img.shape[0] // 5
    north_west = img[:cell, :cell].reshape(-1, 3).mean(0)
    south_east = img[-cell:, -cell:].reshape(-1, 3).mean(0)
    assert north_west[0] > north_west[1] + 0.2 and north_west[0] > north_west[2]  # red: no-fly
    assert south_east[1] > 0.8 and south_east[2] < 0.3  # viridis at the top of the range: yellow
    # The same picture at a threshold below every cell: no red anywhere.
    png_all_ok, _, _ = map_texture(radio, threshold_db=-20.0)
    img_ok = np.asarray(Image.open(io.BytesIO(png_all_ok)).convert("RGB")).astype(float) / 255
    assert not ((img_ok[..., 0] > img_ok[..., 1] + 0.2) & (img_ok[..., 0] > img_ok[..., 2])).any()


def scene_properties(viewer: FleetViewer) -> dict[str, dict[str, object]]:
    out: dict[str, dict[str, object]] = {}
    for c in viewer.scene_commands():
        if c["type"] == "set_property":
            out.setdefault(c["path"], {})[c["property"]] = c["value"]
    return out


def test_update_live_shows_status_and_occupancy() -> None:
    radio = drawn_map(NW_BAD)
    origins = np.array([[150.0, 150.0], [250.0, 250.0], [350.0, 350.0], [450.0, 450.0]])
    destinations = origins[::-1].copy()
    status = np.array([WAITING, ON_BOARD, DELIVERED, HIDDEN])
    with FleetViewer(radio, -3.0) as viewer:
        viewer.update_live(np.array([[150.0, 250.0], [450.0, 50.0]]), status, origins, destinations, t=0,
                           pax_taxi=np.array([-1, 0, 0, -1]))  # fmt: skip
        viewer.update_live(np.array([[250.0, 250.0], [450.0, 150.0]]), status, origins, destinations, t=1,
                           pax_taxi=np.array([-1, 0, 0, -1]))  # fmt: skip
        props = scene_properties(viewer)
        paths = set(viewer.scene_paths())
    visible = {path.removeprefix("/meshcat/"): p["visible"] for path, p in props.items() if "visible" in p}
    assert visible["passengers/S1"] and visible["passengers/S1/marker"] and not visible["passengers/S1/served"]
    assert not visible["passengers/S2/marker"] and visible["passengers/S2/served"] and visible["passengers/D2/marker"]
    assert visible["passengers/S3/served"] and visible["passengers/D3/served"] and not visible["passengers/D3/marker"]
    assert not visible["passengers/S4"] and not visible["passengers/D4"]
    assert visible["taxis/taxi_0/pods/pod_1"] and not visible["taxis/taxi_0/pods/pod_2"]  # one on board
    assert not visible["taxis/taxi_1/pods/pod_1"]
    assert "/meshcat/paths/taxi_0/ribbon" in paths and "/meshcat/paths/taxi_1/ribbon" in paths


def test_update_live_rejects_mismatched_passengers() -> None:
    with FleetViewer(drawn_map(NW_BAD), -3.0) as viewer, pytest.raises(ValueError, match="same passengers"):
        viewer.update_live(np.zeros((1, 2)), np.zeros(3), np.zeros((2, 2)), np.zeros((2, 2)), t=0)


def group_alive(pid: int) -> bool:
    try:
        os.killpg(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_server_is_gone_after_close() -> None:
    viewer = FleetViewer(drawn_map(NW_BAD), -3.0, open_server=True)
    proc = viewer.server_process
    assert proc is not None and proc.poll() is None
    assert viewer.url is not None and viewer.url.startswith("http://127.0.0.1:")  # not every interface
    viewer.update_live(np.array([[150.0, 150.0]]), np.array([WAITING]), np.array([[350.0, 150.0]]),
                       np.array([[350.0, 350.0]]), t=0)  # fmt: skip
    viewer.close()
    assert proc.poll() is not None
    assert not group_alive(proc.pid)
    viewer.close()  # idempotent
    assert "/meshcat/radio_map" in viewer.html()  # the scene outlives the server


def test_server_is_gone_after_an_exception_in_the_with_block() -> None:
    with pytest.raises(RuntimeError, match="boom"), FleetViewer(drawn_map(NW_BAD), -3.0, open_server=True) as viewer:
        proc = viewer.server_process
        assert proc is not None and proc.poll() is None
        raise RuntimeError("boom")
    assert proc.poll() is not None
    assert not group_alive(proc.pid)


def test_server_is_gone_when_the_program_forgets_to_close() -> None:
    script = textwrap.dedent(
        """
        import numpy as np
        from uamfleet.radio import RadioMap
        from uamfleet.viz.meshcat_view import FleetViewer
        viewer = FleetViewer(RadioMap(np.zeros((3, 3)), 100.0), -3.0, open_server=True)
        print(viewer.server_process.pid, flush=True)
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    pid = int(out.stdout.strip().splitlines()[-1])
    try:
        assert not group_alive(pid)
    finally:
        if group_alive(pid):
            os.killpg(pid, signal.SIGKILL)


def test_human_render_mode_opens_and_closes_the_viewer() -> None:
    env = uamfleet.parallel_env("berlin_p4", render_mode="human")
    try:
        assert "human" in env.metadata["render_modes"]
        obs, _ = env.reset(seed=0)
        assert env.render() is None
        viewer = env._viewer
        proc = viewer.server_process
        assert proc is not None and proc.poll() is None
        action = int(np.flatnonzero(obs["uam_0"]["action_mask"])[0])
        env.step({"uam_0": action})
        env.render()
        assert env._viewer is viewer  # opened once
        assert "/meshcat/taxis/taxi_0" in viewer.scene_paths()
    finally:
        env.close()
    assert proc.poll() is not None
    assert not group_alive(proc.pid)


def test_core_never_imports_meshcat() -> None:
    script = (
        "import sys, uamfleet, uamfleet.viz, uamfleet.viz.meshcat_view, uamfleet.viz.strip\n"
        "env = uamfleet.parallel_env('berlin_p4', render_mode='rgb_array'); env.reset(seed=0); env.render()\n"
        "print(sorted(m for m in sys.modules if m == 'meshcat' or m.startswith('meshcat.')))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
