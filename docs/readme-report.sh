#!/bin/sh
# Puts the Markdown an `incise report` run wrote (DIR/summary.md, DIR/growth.md,
# DIR/resolution.md, DIR/stability.md) into README.md, each between its markers (<!-- report:summary --> … <!-- /report:summary -->),
# so that the README's report figures are never typed by hand. Run from the repository root:
#   incise report $(dirname fixtures/*/scene.toml) --out report && sh docs/readme-report.sh report
set -eu
dir=${1:?usage: sh docs/readme-report.sh REPORT_DIR}
for part in summary growth resolution stability; do
    file="$dir/$part.md"
    [ -f "$file" ] || { echo "$file: missing (run incise report --out $dir first)" >&2; exit 1; }
    grep -qx "<!-- report:$part -->" README.md \
        || { echo "README.md: no <!-- report:$part --> marker" >&2; exit 1; }
    grep -qx "<!-- /report:$part -->" README.md \
        || { echo "README.md: no <!-- /report:$part --> marker" >&2; exit 1; }
    awk -v part="$part" -v file="$file" '
        $0 == "<!-- report:" part " -->" {
            print
            while ((getline line < file) > 0) print line
            skip = 1
            next
        }
        $0 == "<!-- /report:" part " -->" { skip = 0 }
        !skip { print }
    ' README.md > README.md.tmp
    mv README.md.tmp README.md
done
