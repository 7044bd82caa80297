#!/bin/sh
# The README's pictures of `incise report`: one screenshot per section of REPORT_DIR/index.html,
# as headless Chromium renders it 1280 px wide, written to docs/report-<section>.png.
#
#   cargo run --release -p incise -- report $(dirname fixtures/*/scene.toml) --out report
#   sh docs/report-screenshots.sh report
#
# Needs python3 and Debian's chromium (apt-get install chromium); nothing else uses them.
set -eu
dir=${1:?usage: docs/report-screenshots.sh REPORT_DIR}
docs=$(dirname "$0")
python3 - "$dir" <<'PY'
import sys
d = sys.argv[1]
page = open(f"{d}/index.html").read()
head = page[: page.index("<h1>")]
ids = ["error", "resolution", "worst", "growth", "stability", "memory"]
starts = [page.index(f' id="{k}"') for k in ids]
starts = [page.rindex("<h", 0, a) for a in starts]
for i, k in enumerate(ids):
    b = starts[i + 1] if i + 1 < len(ids) else len(page)
    open(f"{d}/section-{k}.html", "w").write(head + page[starts[i]:b] + "</body></html>")
PY
for s in error:1000 resolution:420 worst:1000 growth:760 stability:1000 memory:620; do
    name=${s%%:*}
    height=${s##*:}
    chromium --headless --no-sandbox --disable-gpu --hide-scrollbars \
        --window-size=1280,"$height" --screenshot="$docs/report-$name.png" \
        "file://$(realpath "$dir")/section-$name.html" 2>/dev/null
    rm "$dir/section-$name.html"
done
