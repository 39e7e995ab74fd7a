"""The offline page: a scene's meshcat commands replayed by meshcat's own viewer, inline in one HTML file.

The page needs no network and no server. Its address may end in ``#t=T`` (the animation paused at T s;
``#t=end``: the last frame) and ``#cam=X,Y,Z`` (the camera in scene units): what ``scripts/screenshot.sh`` uses.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

from uamfleet.viz.meshcat_server import meshcat_modules


def static_html(commands: list[bytes], title: str, manifest: dict[str, Any]) -> str:
    """The page replaying ``commands`` (packed meshcat commands, in order) under ``title``; ``manifest`` is
    embedded as JSON (``<script id="uamfleet-scene">``) for tools that read the page."""
    js_path = Path(meshcat_modules().meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    meshcat_js = js_path.read_text(encoding="utf-8").replace("</script", "<\\/script")
    encoded = ",\n".join(f'"{base64.b64encode(c).decode("ascii")}"' for c in commands)
    manifest_json = json.dumps(manifest, ensure_ascii=False).replace("</", "<\\/")
    return _PAGE.format(
        title=html.escape(title),
        meshcat_js=meshcat_js,
        manifest=manifest_json,
        commands=encoded,
    )


_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; overflow: hidden; background: linear-gradient(#f4f6f9, #b8c4d3); }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#uamfleet-title {{ position: absolute; left: 12px; top: 10px; padding: 6px 10px; border-radius: 6px;
  font: 14px/1.35 sans-serif; background: rgba(255, 255, 255, 0.85); max-width: 55vw; }}
#uamfleet-title small {{ color: #555; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="uamfleet-title"><b>{title}</b><br><small>drag: orbit, right-drag: pan, wheel: zoom;
Open Controls &rsaquo; Animations to replay or scrub</small></div>
<script>
{meshcat_js}
</script>
<script type="application/json" id="uamfleet-scene">{manifest}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var uamfleetCommands = [
{commands}
];
function uamfleetBytes(b64) {{
  var s = atob(b64), out = new Uint8Array(s.length);
  for (var i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}}
uamfleetCommands.forEach(function (c) {{ viewer.handle_command_bytearray(uamfleetBytes(c)); }});
// #cam=X,Y,Z: camera position in scene units (km from the map centre, z up); it looks at the map centre.
var uamfleetCam = /[#&]cam=(-?[0-9.]+),(-?[0-9.]+),(-?[0-9.]+)/.exec(location.hash);
if (uamfleetCam) {{
  var c = uamfleetCam.slice(1).map(parseFloat);
  viewer.set_property(["Cameras", "default", "rotated", "<object>"], "position", [c[0], c[2], -c[1]]);
}}
// #t=SECONDS (or #t=end): show the animation paused at that time.
var uamfleetSeek = /[#&]t=(end|[0-9.]+)/.exec(location.hash);
if (uamfleetSeek && viewer.animator.actions.length > 0) {{
  viewer.animator.pause();
  viewer.animator.seek(uamfleetSeek[1] === "end" ? viewer.animator.duration : parseFloat(uamfleetSeek[1]));
}}
</script>
</body>
</html>
"""
