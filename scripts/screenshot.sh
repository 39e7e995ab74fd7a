#!/usr/bin/env bash
# Screenshot a page written by `python -m eval.render` with headless Chromium (software WebGL).
#
#   scripts/screenshot.sh HTML PNG [VIEW]
#
# VIEW goes after '#' in the page's address: "t=8" shows the animation paused at 8 s, "t=end" its last frame,
# "cam=X,Y,Z" puts the camera at X, Y, Z (km from the scene's centre, z up), e.g. "t=8&cam=0.3,-2.6,0.7".
# WINDOW (default 1400,900) sets the size in pixels.
#
# meshcat draws with WebGL. Headless Chromium has no GPU here: ANGLE on SwiftShader (a CPU Vulkan) renders it;
# --use-angle=swiftshader picks it and --enable-unsafe-swiftshader keeps newer Chromium from refusing the
# software fallback. (--use-gl=swiftshader gives no WebGL at all with Debian's Chromium 156: a blank scene.)
# No host name resolves (--host-resolver-rules): the page must draw from what it carries.
set -euo pipefail

if [ $# -lt 2 ] || [ $# -gt 3 ]; then
    echo "usage: $0 HTML PNG [VIEW]   e.g. $0 berlin.html berlin.png t=8" >&2
    exit 2
fi
html=$(realpath "$1")
png=$(realpath -m "$2")
view=${3:-}
[ -f "$html" ] || { echo "no such page: $1" >&2; exit 2; }

if [ ! -x /usr/bin/chromium ]; then
    echo "installing Debian's chromium (once)..." >&2
    if [ "$(id -u)" -eq 0 ]; then
        apt-get update && apt-get install -y chromium
    else
        sudo apt-get update && sudo apt-get install -y chromium
    fi
fi

profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
url="file://$html"
[ -n "$view" ] && url="$url#$view"
mkdir -p "$(dirname "$png")"
rm -f "$png"
/usr/bin/chromium --headless --no-sandbox --disable-gpu --disable-background-networking \
    --disable-component-update --disable-sync --no-first-run --hide-scrollbars \
    --use-angle=swiftshader --enable-unsafe-swiftshader --host-resolver-rules="MAP * ~NOTFOUND" \
    --user-data-dir="$profile" --window-size="${WINDOW:-1400,900}" --virtual-time-budget=8000 \
    --screenshot="$png" "$url" >/dev/null 2>"$profile/chromium.log" || {
    cat "$profile/chromium.log" >&2
    exit 1
}
[ -s "$png" ] || { echo "chromium wrote no screenshot:" >&2; cat "$profile/chromium.log" >&2; exit 1; }
echo "wrote $png"
