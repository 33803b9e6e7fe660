#!/usr/bin/env bash
# Loads OUT_DIR/index.html in headless Chromium, takes a screenshot, and fails when the page
# does not load or any <img> on it is broken.
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
echo "report ok: $images images load; screenshot: ${2:-(temporary, not kept)}"
