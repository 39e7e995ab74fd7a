"""3-D view of a fleet over its radio map (meshcat): a live viewer, and one self-contained offline HTML page.

The viewer draws what it is given (a :class:`RadioMap`, a recorded :class:`~uamfleet.rollout.Trajectory`, or a
live state: positions and passenger status), never the simulator itself.

Scene (paths under meshcat's ``/meshcat`` root; the names are stable, tests and users look for them):

- ``ground`` (``ground/slab`` and ``ground/grid``: 500 m lines, 1 km beyond 5 km a side) at z = 0.
- ``radio_map``: the expected-SINR raster at flight altitude as a thin textured slab: viridis for cells at or
  above the threshold, **dark red with light stripes below it** (no-fly: the taxis may not fly there),
  near-black where the planner computed nothing (N.C.). One texel per raster cell up to 1024 cells a side
  (Berlin's 328 x 327 raster is drawn at full resolution, no downsampling: a texture costs far less than a
  vertex-coloured mesh); larger rasters are reduced by an integer stride, a reduced cell being no-fly when any
  of its cells is (conservative), and the legend says so.
- ``towers/gbs_<i>``: each ground base station as a mast from the ground to its height with a red antenna, a
  thin red line up to the map, and a white ring on the map above it (the map hides the masts from above: orbit
  low to see them).
- ``legend``: a sprite (always facing the camera) with the title, the colour bar and threshold, the symbols,
  the taxi colours and the vertical scale.
- ``passengers/S<k>`` and ``passengers/D<k>`` (k = passenger index + 1): origin (white cone) and destination
  (white block) with a label; hidden until the request's release step, grey once served (the ``marker`` and
  ``served`` children swap).
- ``taxis/taxi_<a>``: a small multicopter (body in the taxi's colour, arms, rotors, a line down to its shadow on
  the ground, a label) with one yellow pod on its roof per passenger on board.
- ``paths/taxi_<a>``: the path as a thin ``line`` (all of it), a start disc, and a white-outlined ribbon that
  grows behind the taxi during the animation (``piece_<step>`` children).

Frame and scale: 1 scene unit = 1 km, x east, y north, z up. The operating square's centre sits at
``FleetViewer.shift``, 0.16 map sides west of the origin, so that the map and the legend east of it are centred
on the origin, which meshcat's camera orbits. Heights are exaggerated by ``z_scale`` (default
``0.18 * side_m / altitude_m``, x5.9 for Berlin: a 3.3 km map at 100 m altitude would look flat); horizontal
sizes of markers and taxis are symbolic (fractions of the map side), not to scale.

A trajectory plays as a meshcat animation, one key frame per env step (``seconds_per_step`` of playback each;
Open Controls > Animations to replay or scrub). The exported page shows the animation paused at ``T`` s when
its address ends in ``#t=T`` (``#t=end``: the last frame), and puts the camera at ``X, Y, Z`` (scene units)
with ``#cam=X,Y,Z``: what ``scripts/screenshot.sh`` uses.

With ``open_server=True`` the viewer starts meshcat's web server (bound to ``host``, 127.0.0.1 by default:
meshcat itself binds every interface) in its own process group; :meth:`FleetViewer.close` kills that group,
and so do the context manager, garbage collection and interpreter exit. meshcat is imported lazily, on the
first viewer: ``import uamfleet`` never imports it.

This module is the scene; its neighbours hold the rest of the viewer: :mod:`uamfleet.viz.meshcat_server` (the
meshcat import and the server process), :mod:`uamfleet.viz.textures` (map texture, labels, legend),
:mod:`uamfleet.viz.page` (the offline HTML page) and :mod:`uamfleet.viz.colours` (the shared palette).
"""

from __future__ import annotations

import math
import os
import subprocess
import weakref
from pathlib import Path
from types import SimpleNamespace, TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np

from uamfleet.io import write_text_atomic
from uamfleet.radio import RadioMap
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD
from uamfleet.viz.colours import ANTENNA_HEX, PASSENGER_HEX, POD_HEX, SERVED_HEX, TAXI_HEX, TOWER_HEX
from uamfleet.viz.meshcat_server import Recorder, start_server, stop_server
from uamfleet.viz.meshcat_server import meshcat_modules as _mc
from uamfleet.viz.page import static_html
from uamfleet.viz.strip import onboard_counts, stop_events
from uamfleet.viz.textures import grid_spacing_m, label_png, legend_png, map_texture

if TYPE_CHECKING:
    from uamfleet.rollout import Trajectory

UNIT_M = 1000.0
"""Metres per scene unit (meshcat's camera clips beyond 100 units and its lights suit scenes of a few units)."""


class FleetViewer:
    """A meshcat scene of one radio map, its threshold, and a fleet (a recorded trajectory or a live state).

    ``open_server=False`` (default) starts no process: build the scene and :meth:`export_html` it.
    ``open_server=True`` also streams it to meshcat's web server (see :attr:`url`). Always :meth:`close` the
    viewer (or use it as a context manager); the server is killed then, and at exit in any case.
    """

    def __init__(
        self,
        radio: RadioMap,
        threshold_db: float,
        *,
        open_server: bool = False,
        host: str = "127.0.0.1",
        z_scale: float | None = None,
        seconds_per_step: float = 0.25,
        title: str | None = None,
    ) -> None:
        if not isinstance(radio, RadioMap):
            raise TypeError(f"radio must be a RadioMap, got {type(radio).__name__}")
        if not math.isfinite(threshold_db):
            raise ValueError(f"threshold_db={threshold_db!r} must be a finite threshold in dB, e.g. -3.0")
        if not (seconds_per_step > 0 and math.isfinite(seconds_per_step)):
            raise ValueError(f"seconds_per_step={seconds_per_step!r} must be a positive number of seconds")
        self.radio, self.threshold_db = radio, float(threshold_db)
        self.side_m = float(radio.side_m or 0.0)
        self.z_scale = float(z_scale) if z_scale is not None else max(1.0, 0.18 * self.side_m / radio.altitude_m)
        self.seconds_per_step = float(seconds_per_step)
        self.title = title or f"{radio.label}, γ_T = {self.threshold_db:g} dB"
        self.map_z = radio.altitude_m * self.z_scale / UNIT_M  # scene units
        # The map sits west of the origin so that map + legend (east of it) are centred where the camera looks.
        self.shift = np.array([-0.16 * self.side_m / UNIT_M, 0.0])
        s = self.side_m / UNIT_M
        self.sizes = SimpleNamespace(taxi=s / 16, marker=s / 45, tower=s / 170, label=s / 26, ribbon=s / 200)
        self.num_frames = 0
        self._server: subprocess.Popen[bytes] | None = None
        self._finalizer: weakref.finalize | None = None
        self._rec = Recorder()
        self._sent: dict[tuple[str, str], Any] = {}
        self._live_taxis = 0
        self._live_pax: tuple[np.ndarray, np.ndarray] | None = None
        self._trails: list[list[np.ndarray]] = []
        self._last_t = -1
        self.url: str | None = None
        mc = _mc()
        if open_server:
            proc, zmq_url, web_url, log = start_server(host)
            try:
                window = mc.meshcat.visualizer.ViewerWindow(zmq_url=zmq_url, start_server=False, server_args=[])
            except BaseException:
                stop_server(proc, None, log)
                raise
            self._server, self._rec.live, self.url = proc, window, web_url
            self._finalizer = weakref.finalize(self, stop_server, proc, window, log)
        self.vis = mc.Visualizer(window=self._rec)
        self._build_static()

    # ---- lifetime ------------------------------------------------------------------------------------------
    @property
    def server_process(self) -> subprocess.Popen[bytes] | None:
        """The meshcat server process (None without a server)."""
        return self._server

    def close(self) -> None:
        """Kill the server's process group (if any) and wait for it. Idempotent; exporting still works."""
        self._rec.live = None
        if self._finalizer is not None:
            self._finalizer()

    def __enter__(self) -> FleetViewer:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # ---- geometry helpers ----------------------------------------------------------------------------------
    def xy(self, points_m: Any) -> np.ndarray:
        """World metres [..., 2] -> scene units [..., 2] (map centre at ``shift``)."""
        return (np.asarray(points_m, dtype=np.float64) - self.side_m / 2) / UNIT_M + self.shift

    def _place(self, path: str, x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0) -> None:
        tf = _mc().tf
        matrix = tf.rotation_matrix(yaw, [0, 0, 1])
        matrix[:3, 3] = [x, y, z]
        self.vis[path].set_transform(matrix)

    def _set_visible(self, path: str, visible: bool) -> None:
        key = (path, "visible")
        if self._sent.get(key) != visible:
            self._sent[key] = visible
            self.vis[path].set_property("visible", bool(visible))

    def _mesh(self, path: str, geometry: Any, colour: int, *, basic: bool = False, opacity: float = 1.0,
              matrix: np.ndarray | None = None, **material: Any) -> None:  # fmt: skip
        g = _mc().g
        kind = g.MeshBasicMaterial if basic else g.MeshLambertMaterial
        self.vis[path].set_object(geometry, kind(color=colour, opacity=opacity, **material))
        if matrix is not None:
            self.vis[path].set_transform(matrix)

    def _sprite(self, path: str, png: bytes, aspect: float, height: float, z: float = 0.0) -> None:
        mc = _mc()
        texture = mc.g.ImageTexture(mc.g.PngImage(png), minFilter=1006, magFilter=1006)  # THREE.LinearFilter
        material = mc.SpriteMaterial(map=texture, transparent=True, depthTest=False, sizeAttenuation=True)
        self.vis[path].set_object(mc.Sprite(mc.SpriteShape(height * aspect, height), material))
        self._place(path, z=z)

    def _label(self, path: str, text: str, z: float, fg: str = "#ffffff", bg: str = "#000000c8") -> None:
        png, aspect = label_png(text, fg, bg)
        self._sprite(path, png, aspect, self.sizes.label, z)

    # ---- static scene --------------------------------------------------------------------------------------
    def _build_static(self) -> None:
        g, tf = _mc().g, _mc().tf
        vis = self.vis
        vis["/Grid"].set_property("visible", False)
        vis["/Axes"].set_property("visible", False)
        vis["/Background"].set_property("visible", False)  # the page's own background shows through
        s = self.side_m / UNIT_M
        # Camera: south of the map, looking north and down at the origin; its parent frame is y-up.
        cam = np.array([0.0, -0.74 * s, 0.84 * s + 0.5 * self.map_z])
        vis["/Cameras/default/rotated/<object>"].set_property("position", [cam[0], cam[2], -cam[1]])
        # Ground with a grid (500 m; 1 km on larger maps).
        extent = 1.1 * s
        at = tf.translation_matrix([self.shift[0], self.shift[1], -0.001])
        self._mesh("ground/slab", g.Box([extent, extent, 0.002]), 0xCFD8DC, matrix=at)
        ticks = np.arange(0.0, self.side_m + 1e-6, grid_spacing_m(self.radio))
        ends = [((t, 0.0), (t, self.side_m)) for t in ticks] + [((0.0, t), (self.side_m, t)) for t in ticks]
        lines = self.xy(np.array(ends))  # [L, 2, 2]
        points = np.concatenate([lines, np.full((*lines.shape[:2], 1), 0.0005)], axis=-1).reshape(-1, 3)
        points = points.astype(np.float32).T
        vis["ground/grid"].set_object(g.LineSegments(g.PointsGeometry(points), g.LineBasicMaterial(color=0x90A4AE)))
        self._build_map()
        self._build_towers()
        self._build_legend(num_taxis=0)

    def _build_map(self) -> None:
        g, tf = _mc().g, _mc().tf
        png, self.raster_stride, (x0, x1, y0, y1) = map_texture(self.radio, self.threshold_db)
        thickness = 0.004
        # Nearest when magnified (crisp cells), mipmaps when minified (no moiré from the stripes).
        texture = g.ImageTexture(g.PngImage(png), magFilter=1003, minFilter=1008)
        (cx, cy), (w, h) = self.xy([(x0 + x1) / 2, (y0 + y1) / 2]), ((x1 - x0) / UNIT_M, (y1 - y0) / UNIT_M)
        self.vis["radio_map"].set_object(g.Box([w, h, thickness]), g.MeshBasicMaterial(map=texture))
        self.vis["radio_map"].set_transform(tf.translation_matrix([cx, cy, self.map_z - thickness / 2]))

    def _build_towers(self) -> None:
        g, tf = _mc().g, _mc().tf
        r = self.sizes.tower
        upright = tf.rotation_matrix(math.pi / 2, [1, 0, 0])  # three.js cylinders stand along y
        for i, bs in enumerate(self.radio.base_stations):
            path = f"towers/gbs_{i}"
            (x, y), h = self.xy([bs.x_m, bs.y_m]), max(bs.height_m, 1.0) * self.z_scale / UNIT_M
            self._place(path, x, y)
            self._mesh(
                f"{path}/mast", g.Cylinder(h, r), TOWER_HEX, matrix=tf.translation_matrix([0, 0, h / 2]) @ upright
            )
            self._mesh(f"{path}/antenna", g.Sphere(2.0 * r), ANTENNA_HEX, matrix=tf.translation_matrix([0, 0, h]))
            link = np.array([[0, 0, h], [0, 0, self.map_z]], dtype=np.float32).T
            self.vis[f"{path}/link"].set_object(
                g.Line(g.PointsGeometry(link), g.LineBasicMaterial(color=ANTENNA_HEX, opacity=0.7))
            )
            disc = tf.translation_matrix([0, 0, self.map_z + 0.002]) @ upright
            self._mesh(f"{path}/on_map", g.Cylinder(0.002, 2.2 * r), 0xFFFFFF, basic=True, matrix=disc)
            dot = tf.translation_matrix([0, 0, 0.001]) @ disc
            self._mesh(f"{path}/on_map_dot", g.Cylinder(0.002, 1.3 * r), TOWER_HEX, basic=True, matrix=dot)

    def _build_legend(self, num_taxis: int) -> None:
        png, aspect = legend_png(self.radio, self.threshold_db, self.title, num_taxis, self.z_scale,
                                 self.raster_stride)  # fmt: skip
        s = self.side_m / UNIT_M
        height = 0.8 * s
        self._sprite("legend", png, aspect, height)
        east = self.shift[0] + 0.5 * s
        self._place("legend", east + 0.08 * s + 0.5 * height * aspect, self.shift[1] - 0.05 * s, self.map_z)

    # ---- dynamic objects -----------------------------------------------------------------------------------
    def _build_passengers(self, origins_m: np.ndarray, destinations_m: np.ndarray) -> None:
        g, tf = _mc().g, _mc().tf
        self.vis["passengers"].delete()
        self._sent = {k: v for k, v in self._sent.items() if not k[0].startswith("passengers")}
        m = self.sizes.marker
        upright = tf.rotation_matrix(math.pi / 2, [1, 0, 0])
        cone = tf.translation_matrix([0, 0, 0.9 * m]) @ upright  # tip on the map
        block = tf.translation_matrix([0, 0, 0.5 * m])
        for p, (origin, dest) in enumerate(zip(origins_m, destinations_m, strict=True)):
            for tag, where, shape, matrix in (
                ("S", origin, g.Cylinder(1.8 * m, radiusTop=0.75 * m, radiusBottom=0.0), cone),
                ("D", dest, g.Box([1.2 * m, 1.2 * m, 1.0 * m]), block),
            ):
                path = f"passengers/{tag}{p + 1}"
                x, y = self.xy(where)
                self._place(path, x, y, self.map_z)
                self._mesh(f"{path}/marker", shape, PASSENGER_HEX, matrix=matrix)
                self._mesh(f"{path}/served", shape, SERVED_HEX, opacity=0.55, matrix=matrix)
                self._set_visible(f"{path}/served", False)
                self._label(f"{path}/label", f"{tag}{p + 1}", z=2.0 * m + 0.6 * self.sizes.label)

    def _build_taxis(self, num_taxis: int, seats: int) -> None:
        g, tf = _mc().g, _mc().tf
        self.vis["taxis"].delete()
        self.vis["paths"].delete()
        self._sent = {k: v for k, v in self._sent.items() if not k[0].startswith(("taxis", "paths"))}
        L = self.sizes.taxi
        upright = tf.rotation_matrix(math.pi / 2, [1, 0, 0])
        for a in range(num_taxis):
            colour = int(TAXI_HEX[a % len(TAXI_HEX)][1:], 16)
            path = f"taxis/taxi_{a}"
            self._mesh(f"{path}/body", g.Box([L, 0.42 * L, 0.22 * L]), colour)
            self._mesh(f"{path}/cabin", g.Box([0.3 * L, 0.34 * L, 0.1 * L]), 0x263238,
                       matrix=tf.translation_matrix([0.22 * L, 0, 0.14 * L]))  # fmt: skip
            for k, yaw in enumerate((math.pi / 4, -math.pi / 4)):
                self._mesh(f"{path}/arm_{k}", g.Box([1.45 * L, 0.06 * L, 0.04 * L]), 0x424242,
                           matrix=tf.rotation_matrix(yaw, [0, 0, 1]))  # fmt: skip
            for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
                at = tf.translation_matrix([0.51 * sx * L, 0.51 * sy * L, 0.06 * L]) @ upright
                self._mesh(f"{path}/rotor_{k}", g.Cylinder(0.015 * L, 0.24 * L), 0x607D8B, opacity=0.75, matrix=at)
            for k in range(seats):
                at = tf.translation_matrix([(-0.2 + 0.2 * k) * L, 0, 0.2 * L])
                self._mesh(f"{path}/pods/pod_{k + 1}", g.Sphere(0.11 * L), POD_HEX, matrix=at)
                self._set_visible(f"{path}/pods/pod_{k + 1}", False)
            drop = np.array([[0, 0, -0.1 * L], [0, 0, -self.map_z]], dtype=np.float32).T
            self.vis[f"{path}/drop"].set_object(
                g.Line(g.PointsGeometry(drop), g.LineBasicMaterial(color=colour, opacity=0.8))
            )
            shadow = tf.translation_matrix([0, 0, -self.map_z + 0.002]) @ upright
            self._mesh(f"{path}/shadow", g.Cylinder(0.002, 0.45 * L), 0x000000, basic=True, opacity=0.35,
                       matrix=shadow)  # fmt: skip
            self._label(f"{path}/label", f"taxi {a}", z=1.1 * L, fg=TAXI_HEX[a % len(TAXI_HEX)], bg="#ffffffd9")
        self._live_taxis = num_taxis

    def _set_path(self, a: int, trail_m: np.ndarray, chunk_steps: int | None = None) -> list[tuple[str, int]]:
        """Taxi ``a``'s path [K, 2] (metres), just above the map: a thin ``line`` (the whole path), a start disc
        and a white-outlined ribbon; in pieces of ``chunk_steps`` steps when given (the animation reveals each
        piece when the taxi starts flying it). Returns the pieces' paths with their first step."""
        g, tf = _mc().g, _mc().tf
        colour = int(TAXI_HEX[a % len(TAXI_HEX)][1:], 16)
        path = f"paths/taxi_{a}"
        self.vis[path].delete()
        z = self.map_z + 0.003 + 0.0008 * a
        pts = _distinct(self.xy(trail_m))
        if len(pts) < 2:
            return []
        start = tf.translation_matrix([pts[0, 0], pts[0, 1], z]) @ tf.rotation_matrix(math.pi / 2, [1, 0, 0])
        self._mesh(f"{path}/start", g.Cylinder(0.003, 3.5 * self.sizes.ribbon), colour, basic=True, matrix=start)
        line = np.column_stack([pts, np.full(len(pts), z + 0.0004)]).astype(np.float32).T
        self.vis[f"{path}/line"].set_object(g.Line(g.PointsGeometry(line), g.LineBasicMaterial(color=colour)))
        step = len(trail_m) if chunk_steps is None else max(1, chunk_steps)
        pieces = []
        for first in range(0, len(trail_m) - 1, step):
            piece = _distinct(self.xy(trail_m[first : first + step + 1]))
            if len(piece) < 2:
                continue
            name = f"{path}/piece_{first}" if chunk_steps is not None else path
            for part, width, hexcolour, dz in (("outline", 2.2, 0xFFFFFF, 0.0), ("ribbon", 1.2, colour, 0.0002)):
                vertices, faces = _ribbon(piece, width * self.sizes.ribbon, z + dz)
                self._mesh(f"{name}/{part}", g.TriangularMeshGeometry(vertices, faces), hexcolour, basic=True)
            pieces.append((name, first))
        return pieces

    # ---- public API ----------------------------------------------------------------------------------------
    def show_trajectory(self, traj: Trajectory, title: str | None = None) -> None:
        """Draw a recorded episode: paths, stops, and the taxis animated one key frame per step."""
        if title is not None:
            self.title = title
        positions = traj.positions_m  # [A, T + 1, 2]
        num_taxis, num_frames = positions.shape[0], positions.shape[1]
        exists = np.flatnonzero(traj.pax_exists)
        self._build_legend(num_taxis)
        self._build_passengers(traj.origin_m[exists], traj.destination_m[exists])
        self._live_pax = None
        self._build_taxis(num_taxis, traj.seats)
        chunk = max(1, math.ceil((num_frames - 1) / 60))  # the path grows behind the taxi in <= 60 pieces
        pieces = [piece for a in range(num_taxis) for piece in self._set_path(a, positions[a], chunk)]
        self.num_frames = num_frames
        anim = _mc().animation.Animation(default_framerate=1.0 / self.seconds_per_step)
        last = num_frames - 1
        self._animate_taxis(anim, positions)
        frames = np.arange(num_frames)
        for path, first in pieces:
            _bool_track(anim, self.vis, path, frames > first, last)
            self._set_visible(path, False)
        onboard = onboard_counts(traj)  # [A, T + 1]
        for a in range(num_taxis):
            for k in range(traj.seats):
                _bool_track(anim, self.vis, f"taxis/taxi_{a}/pods/pod_{k + 1}", onboard[a] > k, last)
        self._animate_passengers(anim, traj, exists)
        self.vis.set_animation(anim, play=True, repetitions=1)

    def _animate_taxis(self, anim: Any, positions: np.ndarray) -> None:
        """One key frame per step: each taxi at its position [A, T + 1, 2], turned along its heading."""
        mc = _mc()
        yaw = _headings(positions)  # [A, T + 1]
        hover = 0.35 * self.sizes.taxi
        xy = self.xy(positions)
        for t in range(positions.shape[1]):
            with anim.at_frame(self.vis, t) as frame:
                for a in range(positions.shape[0]):
                    matrix = mc.tf.rotation_matrix(yaw[a, t], [0, 0, 1])
                    matrix[:3, 3] = [xy[a, t, 0], xy[a, t, 1], self.map_z + hover]
                    frame[f"taxis/taxi_{a}"].set_transform(matrix)
                    if t == 0:
                        self.vis[f"taxis/taxi_{a}"].set_transform(matrix)

    def _animate_passengers(self, anim: Any, traj: Trajectory, exists: np.ndarray) -> None:
        """Each stop appears at its release and turns to "served" at its pick-up or drop-off."""
        num_frames = traj.positions_m.shape[1]
        frames, last = np.arange(num_frames), num_frames - 1
        index = {int(p): i for i, p in enumerate(exists)}
        served_at: dict[tuple[str, int], int] = {}
        for e in stop_events(traj):
            served_at[("S" if e.kind == "pickup" else "D", e.passenger)] = e.step
        for p, i in index.items():
            released = frames >= int(traj.release_step[p])
            for tag in ("S", "D"):
                path = f"passengers/{tag}{i + 1}"
                step = served_at.get((tag, p))
                served = frames >= (num_frames if step is None else step)
                _bool_track(anim, self.vis, path, released, last)
                _bool_track(anim, self.vis, f"{path}/marker", ~served, last)
                _bool_track(anim, self.vis, f"{path}/served", served, last)
                self._set_visible(path, bool(released[0]))

    def update_live(
        self,
        positions_m: Any,
        pax_status: Any,
        origins: Any,
        destinations: Any,
        t: int,
        *,
        pax_taxi: Any = None,
        seats: int = 2,
    ) -> None:
        """Show one live state: taxi positions [A, 2] (m), passenger status [P] (``uamfleet.types`` codes),
        origins / destinations [P, 2] (m) and the step ``t``; ``pax_taxi`` [P] (the carrying taxi, -1 for none)
        fills the taxis' pods. Paths accumulate until ``t`` goes back (a new episode)."""
        pos = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
        status = np.asarray(pax_status).reshape(-1)
        origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
        destinations = np.asarray(destinations, dtype=np.float64).reshape(-1, 2)
        if not (len(status) == len(origins) == len(destinations)):
            raise ValueError(
                f"pax_status {status.shape}, origins {origins.shape} and destinations {destinations.shape} must "
                "describe the same passengers: shapes [P], [P, 2], [P, 2]"
            )
        carrier = np.full(len(status), -1) if pax_taxi is None else np.asarray(pax_taxi).reshape(-1)
        if self._live_taxis != len(pos) or t <= self._last_t:
            if self._live_taxis != len(pos):
                self._build_legend(len(pos))
                self._build_taxis(len(pos), max(seats, 1))
            self._trails = [[] for _ in range(len(pos))]
        if self._live_pax is None or not all(
            np.array_equal(u, v) for u, v in zip(self._live_pax, (origins, destinations), strict=True)
        ):
            self._build_passengers(origins, destinations)
            self._live_pax = (origins.copy(), destinations.copy())
        self._last_t = int(t)
        onboard = np.bincount(carrier[(status == ON_BOARD) & (carrier >= 0)], minlength=len(pos))
        self._place_live_taxis(pos, onboard, seats)
        for i in range(len(status)):
            code = int(status[i])
            for tag, done in (("S", code in (ON_BOARD, DELIVERED)), ("D", code == DELIVERED)):
                path = f"passengers/{tag}{i + 1}"
                self._set_visible(path, code != HIDDEN)
                self._set_visible(f"{path}/marker", not done)
                self._set_visible(f"{path}/served", done)

    def _place_live_taxis(self, pos: np.ndarray, onboard: np.ndarray, seats: int) -> None:
        """Each taxi at ``pos`` [A, 2], its trail grown by the new position, its pods filled by ``onboard``."""
        hover = 0.35 * self.sizes.taxi
        for a in range(len(pos)):
            trail = self._trails[a]
            if not trail or not np.array_equal(trail[-1], pos[a]):
                trail.append(pos[a].copy())
                self._set_path(a, np.array(trail))
            yaw = _headings(np.array(trail)[None])[0, -1]
            x, y = self.xy(pos[a])
            self._place(f"taxis/taxi_{a}", x, y, self.map_z + hover, yaw)
            for k in range(max(seats, 1)):
                self._set_visible(f"taxis/taxi_{a}/pods/pod_{k + 1}", bool(onboard[a] > k))

    def scene_paths(self) -> list[str]:
        """Every path the scene holds an object, transform or property at (``/meshcat/radio_map``, ...)."""
        return self._rec.paths()

    def scene_commands(self) -> list[dict[str, Any]]:
        """The scene as decoded meshcat commands (``type``, ``path``, ...), in the order the page replays them."""
        unpack = _mc().umsgpack.unpackb
        return [unpack(c) for c in self._rec.commands()]

    def html(self) -> str:
        """The scene as one self-contained HTML page (meshcat's viewer inline, no network access)."""
        return static_html(self._rec.commands(), self.title, self._manifest())

    def export_html(self, path: str | os.PathLike[str]) -> Path:
        """Write :meth:`html` atomically to ``path``; returns the path."""
        return write_text_atomic(path, self.html())

    def _manifest(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "threshold_db": self.threshold_db,
            "z_scale": self.z_scale,
            "unit_m": UNIT_M,
            "raster_stride": self.raster_stride,
            "frames": self.num_frames,
            "seconds_per_step": self.seconds_per_step,
            "paths": self.scene_paths(),
        }


def _ribbon(pts: np.ndarray, width: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A flat strip of ``width`` along a polyline [K, 2] at height z: vertices [2K, 3], faces [2(K-1), 3]."""
    d = np.diff(pts, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    tangent = np.concatenate([d[:1], d[:-1] + d[1:], d[-1:]])  # vertex tangents: mean of adjacent segments
    tangent /= np.maximum(np.linalg.norm(tangent, axis=-1, keepdims=True), 1e-12)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=-1) * (width / 2)
    left, right = pts + normal, pts - normal
    vertices = np.column_stack([np.stack([left, right], axis=1).reshape(-1, 2), np.full(2 * len(pts), z)])
    k = np.arange(len(pts) - 1) * 2
    faces = np.concatenate([np.stack([k, k + 1, k + 2], -1), np.stack([k + 1, k + 3, k + 2], -1)])
    return vertices.astype(np.float32), faces.astype(np.uint32)


def _distinct(pts: np.ndarray) -> np.ndarray:
    """The points of a polyline [K, 2] without consecutive repeats (a blocked step, a hover)."""
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=-1) > 1e-9])
    return pts[keep]


def _headings(positions_m: np.ndarray) -> np.ndarray:
    """[A, T + 1] yaw (rad) of each taxi: the direction of its last move (its first move at the start)."""
    d = np.diff(positions_m, axis=1)  # [A, T, 2]
    moving = np.linalg.norm(d, axis=-1) > 1e-9
    yaw = np.zeros(positions_m.shape[:2])
    for a in range(positions_m.shape[0]):
        angles = np.arctan2(d[a, :, 1], d[a, :, 0])
        current = angles[np.argmax(moving[a])] if moving[a].any() else 0.0
        for t in range(positions_m.shape[1]):
            if t > 0 and moving[a, t - 1]:
                current = angles[t - 1]
            yaw[a, t] = current
    return np.unwrap(yaw, axis=1)  # no spin the long way round between frames


def _bool_track(anim: Any, vis: Any, path: str, values: np.ndarray, last_frame: int) -> None:
    """A ``visible`` track with keys at frame 0, at every change and at the last frame."""
    values = np.asarray(values, dtype=bool)
    changes = [0, *(np.flatnonzero(values[1:] != values[:-1]) + 1).tolist(), last_frame]
    for t in sorted(set(changes)):
        with anim.at_frame(vis, t) as frame:
            frame[path].set_property("visible", "boolean", bool(values[min(t, len(values) - 1)]))
