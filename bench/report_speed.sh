#!/usr/bin/env bash
# The report writers against a browser, side by side in one run on the same audit: heatwave's
# native PDF (Cairo + Pango) vs Chromium printing heatwave's own report.html to PDF (what a
# user without the PDF writer would do), and the HTML with and without its 3D view. Prints
# wall time, size and pages of each and the heatwave/Chromium ratios.
#   bench/report_speed.sh [--build DIR] [--repeat N] AUDIT_DIR JOB.yaml
# AUDIT_DIR is a `heatwave audit` (or `heatwave demo`: build/demo/audit) output folder.
set -euo pipefail
build=build
repeat=3
while [ $# -gt 2 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --repeat) repeat=$2; shift 2 ;;
    *) break ;;
  esac
done
audit=$(realpath "$1")
job=$(realpath "$2")
heatwave="$build/cli/heatwave"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
now() { date +%s.%N; }
pages() { pdfinfo "$1" | awk '/^Pages:/ {print $2}'; }
size_mb() { awk -v b="$(stat -c %s "$1")" 'BEGIN {printf "%.2f", b / 1e6}'; }

best_pdf=999; best_html=999; best_html3d=999; best_chromium=999
for i in $(seq "$repeat"); do
  t0=$(now)
  "$heatwave" report "$audit" --job "$job" --out "$out/pdf" --no-html --overwrite -q
  t1=$(now)
  "$heatwave" report "$audit" --job "$job" --out "$out/html" --no-pdf --no-3d --overwrite -q
  t2=$(now)
  "$heatwave" report "$audit" --job "$job" --out "$out/html3d" --no-pdf --overwrite -q
  t3=$(now)
  chromium --headless --no-sandbox --disable-gpu --disable-background-networking --disable-component-update \
    --disable-sync --no-first-run --user-data-dir="$out/profile" --host-resolver-rules="MAP * ~NOTFOUND" \
    --no-pdf-header-footer --print-to-pdf="$out/chromium.pdf" "file://$out/html/report.html" 2>/dev/null
  t4=$(now)
  read -r best_pdf best_html best_html3d best_chromium < <(awk -v a="$t0" -v b="$t1" -v c="$t2" -v d="$t3" -v e="$t4" \
    -v p="$best_pdf" -v h="$best_html" -v h3="$best_html3d" -v cr="$best_chromium" 'function min(x, y) { return x < y ? x : y }
    BEGIN { print min(p, b - a), min(h, c - b), min(h3, d - c), min(cr, e - d) }')
done
printf '%-44s %9s %9s %6s\n' "best of $repeat runs" "time s" "size MB" "pages"
printf '%-44s %9.2f %9s %6s\n' "heatwave report.pdf (Cairo + Pango)" "$best_pdf" "$(size_mb "$out/pdf/report.pdf")" "$(pages "$out/pdf/report.pdf")"
printf '%-44s %9.2f %9s %6s\n' "Chromium --print-to-pdf of report.html" "$best_chromium" "$(size_mb "$out/chromium.pdf")" "$(pages "$out/chromium.pdf")"
printf '%-44s %9.2f %9s\n' "heatwave report.html without the 3D view" "$best_html" "$(size_mb "$out/html/report.html")"
printf '%-44s %9.2f %9s\n' "heatwave report.html with the 3D view" "$best_html3d" "$(size_mb "$out/html3d/report.html")"
awk -v p="$best_pdf" -v c="$best_chromium" -v sp="$(stat -c %s "$out/pdf/report.pdf")" -v sc="$(stat -c %s "$out/chromium.pdf")" \
  'BEGIN { printf "heatwave/Chromium PDF: time %.2fx, size %.2fx\n", p / c, sp / sc }'
