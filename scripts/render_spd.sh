#!/usr/bin/env bash
# Renders every Standard Procedural Databases scene (Haines' SPD, NFF files in ../shared/data/spd/) with
# lancer's Whitted mode under the SPD's testing conventions (shared/data/README.md section 2): maximum depth
# 5 with the eye ray at depth 1, every reflected and refracted ray traced (--min-weight 0), lights and
# ambient at sqrt(N) / (2N) (the NFF reader applies it). Deviation: one ray per pixel centre (--spp 1), or
# stratified samples, instead of the SPD's (X+1) x (Y+1) pixel-corner rays.
#
#   scripts/render_spd.sh [--out DIR] [--size WxH] [--spp N] [--accel NAME] [--spd DIR] [--lancer PATH]
#
# Defaults: out/spd, each scene's own resolution (512x512; jacks 256x256), 1 sample, bvh, ../shared/data/spd
# beside the repository, build/apps/lancer/lancer. Writes DIR/NAME.png per scene and DIR/summary.txt with
# lancer's summary of each render (build and render times, rays by kind, Mrays/s).
# The thumbnails of docs/spd/ were made with:  scripts/render_spd.sh --out docs/spd --size 128x128 --spp 4
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
out="$root/out/spd"
size=""
spp=1
accel=bvh
spd="$root/../shared/data/spd"
lancer="$root/build/apps/lancer/lancer"

while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --accel) accel="$2"; shift 2 ;;
    --spd) spd="$2"; shift 2 ;;
    --lancer) lancer="$2"; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "render_spd.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done

if [ ! -x "$lancer" ]; then
  echo "render_spd.sh: no lancer binary at $lancer (run 'make build', or pass --lancer PATH)" >&2
  exit 2
fi
shopt -s nullglob
scenes=("$spd"/*.nff)
if [ ${#scenes[@]} -eq 0 ]; then
  echo "render_spd.sh: no .nff file in $spd (pass --spd DIR)" >&2
  exit 2
fi

mkdir -p "$out"
summary="$out/summary.txt"
: >"$summary"
for scene in "${scenes[@]}"; do
  name="$(basename "$scene" .nff)"
  args=(render "$scene" -o "$out/$name.png" --mode whitted --spp "$spp" --max-depth 5 --min-weight 0
        --accel "$accel")
  if [ -n "$size" ]; then args+=(--size "$size"); fi
  echo "== $name" | tee -a "$summary"
  "$lancer" "${args[@]}" | tee -a "$summary"
done
echo "wrote ${#scenes[@]} pictures and $summary"
