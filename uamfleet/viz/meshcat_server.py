"""meshcat, imported on first use, and its web server in a process of its own.

- :func:`meshcat_modules`: meshcat's modules plus the object types its Python side lacks (sprites); the only
  place meshcat is imported (``import uamfleet`` and ``import uamfleet.viz.*`` never import it).
- :class:`Recorder`: stands in for meshcat's ``ViewerWindow``, keeps the scene (for the offline page) and
  forwards every command to a live server when there is one.
- :func:`start_server` / :func:`stop_server`: meshcat's ZMQ + web server bound to one address (meshcat itself
  binds every interface), in its own process group so that stopping it kills the whole group.
"""

from __future__ import annotations

import functools
import os
import selectors
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from types import SimpleNamespace
from typing import Any

import numpy as np

# meshcat's server with its web server bound to one address (argv[1]) instead of every interface.
_SERVER_SCRIPT = """\
import sys
import tornado.web
_listen = tornado.web.Application.listen
def _listen_on(self, port, address=sys.argv[1], **kwargs):
    return _listen(self, port, address=address, **kwargs)
tornado.web.Application.listen = _listen_on
sys.argv = sys.argv[:1]
from meshcat.servers.zmqserver import main
main()
"""


@functools.cache
def meshcat_modules() -> SimpleNamespace:
    """meshcat's modules plus the few object types its Python side lacks (sprites)."""
    with warnings.catch_warnings():  # meshcat's package import pulls in its server (pyzmq deprecations)
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.animation as animation
        import meshcat.geometry as g
        import meshcat.transformations as tf
        import umsgpack
        from meshcat.visualizer import Visualizer

    class SpriteMaterial(g.GenericMaterial):
        _type = "SpriteMaterial"

    class SpriteShape(g.Box):
        """A sprite's size (three.js sprites are unit squares scaled by the object's matrix)."""

        def __init__(self, width: float, height: float) -> None:
            super().__init__([1e-6, 1e-6, 1e-6])
            self.size = (width, height)

        def intrinsic_transform(self) -> np.ndarray:
            return np.diag([self.size[0], self.size[1], 1.0, 1.0])

    class Sprite(g.Object):
        _type = "Sprite"

        def lower(self) -> dict[str, Any]:
            data: dict[str, Any] = super().lower()
            data["object"]["renderOrder"] = 10  # drawn after the scene (with depthTest off: always on top)
            return data

    return SimpleNamespace(
        meshcat=meshcat, animation=animation, g=g, tf=tf, umsgpack=umsgpack, Visualizer=Visualizer,
        SpriteMaterial=SpriteMaterial, SpriteShape=SpriteShape, Sprite=Sprite,
    )  # fmt: skip


class Recorder:
    """Stands in for meshcat's ``ViewerWindow``: keeps the latest object, transform and properties of every
    path and the animation (what the server keeps), so that the page can be exported with or without a
    server, and forwards every command to the live server when there is one."""

    def __init__(self) -> None:
        self.nodes: dict[str, dict[str, bytes]] = {}  # path -> {"object" | "transform" | "property:<name>": msg}
        self.animation: bytes | None = None
        self.live: Any = None  # meshcat ViewerWindow connected to our server, or None

    def send(self, command: Any) -> None:
        data = command.lower()
        packed: bytes = meshcat_modules().umsgpack.packb(data)
        kind, path = data["type"], data["path"]
        if kind == "set_animation":
            self.animation = packed
        elif kind == "delete":
            for key in [k for k in self.nodes if k == path or k.startswith(path.rstrip("/") + "/")]:
                del self.nodes[key]
        else:
            slot = {"set_object": "object", "set_transform": "transform"}.get(kind, f"property:{data.get('property')}")
            self.nodes.setdefault(path, {})[slot] = packed
        if self.live is not None:
            socket = self.live.zmq_socket
            socket.send_multipart([kind.encode(), path.encode(), packed])
            socket.recv()

    def commands(self) -> list[bytes]:
        """The scene as a list of commands: objects, transforms and properties path by path, the animation
        last (its tracks bind to objects that must exist by then)."""
        out = [msg for node in self.nodes.values() for msg in node.values()]
        return out + ([self.animation] if self.animation is not None else [])

    def paths(self) -> list[str]:
        return list(self.nodes)


def start_server(host: str, timeout_s: float = 30.0) -> tuple[subprocess.Popen[bytes], str, str, Any]:
    """meshcat's ZMQ + web server in a new process group; returns (process, zmq_url, web_url, stderr file)."""
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen(
        [sys.executable, "-u", "-c", _SERVER_SCRIPT, host],
        stdout=subprocess.PIPE,
        stderr=log,
        stdin=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: close() kills the whole group
    )
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    text, urls = "", dict[str, str]()
    deadline = time.monotonic() + timeout_s
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        # Raw reads: a buffered readline could swallow both lines while select() waits for more.
        while not {"zmq_url", "web_url"} <= urls.keys() and time.monotonic() < deadline:
            if sel.select(timeout=0.2):
                chunk = os.read(fd, 4096)
                if not chunk:  # the server exited
                    break
                text += chunk.decode("utf-8", "replace")
                urls = dict(
                    line.split("=", 1) for line in text.split("\n")[:-1] if line.startswith(("zmq_url=", "web_url="))
                )
    if not {"zmq_url", "web_url"} <= urls.keys():
        log.seek(0)
        message = log.read().decode("utf-8", "replace")[-2000:]
        stop_server(proc, None, log)
        raise RuntimeError(f"the meshcat server did not start within {timeout_s:g} s: {text}{message}")
    return proc, urls["zmq_url"], urls["web_url"], log


def stop_server(proc: subprocess.Popen[bytes], window: Any, log: Any) -> None:
    """Close our socket, then SIGTERM (then SIGKILL) the server's process group and reap it."""
    if window is not None:
        window.zmq_socket.close(linger=0)
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        except ProcessLookupError:
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()
    if log is not None:
        log.close()
