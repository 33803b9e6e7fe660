#!/usr/bin/env bash
# Loads OUT_DIR/index.html in headless Chromium, takes a screenshot, and fails when the page
# does not load, any <img> on it is broken, or a chart's legend does not name a series the chart
# draws (read from each chart's SVG: every colour a marker, line or bar is drawn in must also be
# the colour of a legend swatch with a label beside it).
#
#   scripts/check-report.sh OUT_DIR [SCREENSHOT.png]
#
# Needs Debian's `chromium` package. The page itself is not modified: a copy with a <base> pointing
# at OUT_DIR and a small checking script is loaded from a temporary folder.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 OUT_DIR [SCREENSHOT.png]" >&2
    exit 2
fi
out=$(cd "$1" 2>/dev/null && pwd) || { echo "error: $1: no such folder" >&2; exit 2; }
index="$out/index.html"
[[ -f "$index" ]] || { echo "error: $index: no such file" >&2; exit 2; }
browser=$(command -v chromium || command -v chromium-browser || true)
[[ -n "$browser" ]] || { echo "error: chromium not found (Debian: apt-get install -y chromium)" >&2; exit 2; }

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
shot=${2:-$tmp/screenshot.png}

flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
    --disable-background-networking --disable-component-update --disable-sync
    --hide-scrollbars --virtual-time-budget=15000)

# The copy: <base> makes the report's relative links resolve into OUT_DIR; the script marks
# every image once the page has loaded.
check='<script>window.addEventListener("load",function(){var n=0,b=0;'
check+='document.querySelectorAll("img").forEach(function(i){n++;'
check+='if(!i.complete||i.naturalWidth===0){b++;i.setAttribute("data-broken","1");}});'
check+='document.body.setAttribute("data-images",n);document.body.setAttribute("data-broken-images",b);});</script>'
shopt -u patsub_replacement 2>/dev/null || true
page=$(<"$index")
page=${page/<head>/<head><base href=\"file://$out/\">}
page=${page/<\/body>/$check</body>}
printf '%s\n' "$page" > "$tmp/check.html"

"$browser" "${flags[@]}" --user-data-dir="$tmp/profile-dom" --dump-dom "file://$tmp/check.html" \
    > "$tmp/dom.html" 2> "$tmp/chromium-dom.log" || {
    echo "error: chromium failed to load $index:" >&2
    tail -n 20 "$tmp/chromium-dom.log" >&2
    exit 1
}
"$browser" "${flags[@]}" --user-data-dir="$tmp/profile-shot" --window-size=1280,3600 \
    --screenshot="$shot" "file://$index" > /dev/null 2> "$tmp/chromium-shot.log" || {
    echo "error: chromium failed to take a screenshot of $index:" >&2
    tail -n 20 "$tmp/chromium-shot.log" >&2
    exit 1
}

images=$(grep -o 'data-images="[0-9]*"' "$tmp/dom.html" | grep -o '[0-9]*' || true)
broken=$(grep -o 'data-broken-images="[0-9]*"' "$tmp/dom.html" | grep -o '[0-9]*' || true)
if [[ -z "$images" || -z "$broken" ]]; then
    echo "error: $index did not finish loading in headless chromium" >&2
    exit 1
fi
if [[ "$images" -eq 0 ]]; then
    echo "error: $index shows no image (no chart, no run image)" >&2
    exit 1
fi
if [[ "$broken" -ne 0 ]]; then
    echo "error: $broken of $images images on $index are broken:" >&2
    grep -o '<img[^>]*data-broken="1"[^>]*>' "$tmp/dom.html" | grep -o 'src="[^"]*"' >&2
    exit 1
fi
[[ -s "$shot" ]] || { echo "error: no screenshot written to $shot" >&2; exit 1; }

# Legends: every series colour drawn in a chart has a labelled legend swatch.
charts=$(python3 - "$out" "$index" <<'PY'
import re, sys, os
import xml.etree.ElementTree as ET

out, index = sys.argv[1], sys.argv[2]
page = open(index, encoding="utf-8").read()
svgs = sorted(set(re.findall(r'href="(charts/[^"]+\.svg)"', page)))
# Colours of axes, grid and background: not series.
chrome = {"#000000", "#FFFFFF", "#D7D7D7", "#F0F0F0"}
bad = []

def num(v):
    return float(v) if v not in (None, "") else 0.0

def points(e):
    pts = [tuple(map(float, p.split(","))) for p in e.get("points", "").split()]
    return pts

for rel in svgs:
    root = ET.parse(os.path.join(out, rel)).getroot()
    texts, shapes = [], []
    for e in root.iter():
        tag = e.tag.split("}")[-1]
        if tag == "text":
            # Labels: left-aligned, unrotated text (tick labels and axis titles are centred,
            # right-aligned or rotated), at their vertical centre (y is the top with dy 0.76em).
            if e.get("text-anchor", "start") != "start" or e.get("transform"):
                continue
            size = num(e.get("font-size")) or 12.0
            y = num(e.get("y"))
            centre = y + 0.5 * size if e.get("dy") == "0.76em" else y - 0.35 * size
            texts.append((num(e.get("x")), centre, "".join(e.itertext()).strip()))
            continue
        colour = None
        for attr in ("fill", "stroke"):
            c = (e.get(attr) or "").upper()
            if c.startswith("#") and c not in chrome:
                colour = c
        if colour is None:
            continue
        if tag == "circle":
            x, y, r = num(e.get("cx")), num(e.get("cy")), num(e.get("r"))
            box = (x - r, y - r, x + r, y + r)
        elif tag == "rect":
            x, y = num(e.get("x")), num(e.get("y"))
            box = (x, y, x + num(e.get("width")), y + num(e.get("height")))
        elif tag in ("polyline", "polygon", "line"):
            pts = points(e) if tag != "line" else [(num(e.get("x1")), num(e.get("y1"))), (num(e.get("x2")), num(e.get("y2")))]
            if not pts:
                continue
            xs, ys = [p[0] for p in pts], [p[1] for p in pts]
            box = (min(xs), min(ys), max(xs), max(ys))
        else:
            continue
        shapes.append((colour, box))
    def labelled(box):
        # A swatch: small, with a text starting just right of it at the same height.
        x0, y0, x1, y1 = box
        if x1 - x0 > 40 or y1 - y0 > 20:
            return False
        cy = (y0 + y1) / 2
        return any(0 <= tx - x1 <= 30 and abs(ty - cy) <= 10 and t for tx, ty, t in texts)
    drawn = {c for c, _ in shapes}
    legend = {c for c, b in shapes if labelled(b)}
    missing = sorted(drawn - legend)
    if missing:
        bad.append(f"{rel}: drawn in {', '.join(missing)} with no labelled legend entry")
if bad:
    print("\n".join(bad), file=sys.stderr)
    sys.exit(1)
print(len(svgs))
PY
) || { echo "error: a chart's legend misses a series (above)" >&2; exit 1; }
echo "report ok: $images images load; every legend of $charts charts names every series drawn; screenshot: ${2:-(temporary, not kept)}"
