#!/usr/bin/env bash
# lancer under mpirun (docs/distributed.md): 2 ranks give the single process's picture and hits file byte
# for byte, and a scene that one rank cannot read, or runs out of memory on, ends the job with one message
# naming that rank.
# Usage: mpi_test.sh LANCER BUILT_WITH_MPI(ON|OFF) SCENE MESH WORKDIR. Exit 77 (skipped) without MPI.
set -uo pipefail
lancer=$1 built_with_mpi=$2 scene=$3 mesh=$4 work=$5

if [ "$built_with_mpi" != "ON" ] && [ "$built_with_mpi" != "1" ] && [ "$built_with_mpi" != "TRUE" ]; then
  echo "skipped: lancer was built without MPI (LANCER_MPI, libopenmpi-dev)"
  exit 77
fi
if ! command -v mpirun > /dev/null; then
  echo "skipped: mpirun is not installed (openmpi-bin)"
  exit 77
fi
# As the other tests on shared/data, skip rather than fail in a checkout without it.
if [ ! -r "$mesh" ]; then
  echo "skipped: no shared/data in this checkout ($mesh)"
  exit 77
fi
# Open MPI refuses root unless told; CI containers run as root.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpi=(timeout 120 mpirun --oversubscribe)
mkdir -p "$work"
# A machine where Open MPI itself cannot start two processes (no shared memory, no usable network) says so
# and skips: that is no fault of lancer's.
if ! "${mpi[@]}" -np 2 true > "$work/preflight.txt" 2>&1; then
  echo "skipped: mpirun cannot start 2 processes here: $(head -c 400 "$work/preflight.txt")"
  exit 77
fi
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

# 1. A Whitted render (shadow, mirror and refracted rays) and a depth render (an image-wide pass).
for mode in whitted depth; do
  "$lancer" render "$scene" --mode "$mode" --size 96x72 --threads 1 -o "$work/single_$mode.png" > /dev/null ||
    fail "single-process $mode render"
  "${mpi[@]}" -np 2 "$lancer" render "$scene" --mode "$mode" --size 96x72 --threads 1 \
    -o "$work/mpi_$mode.png" > "$work/mpi_$mode.txt" 2>&1 || fail "2-rank $mode render: $(cat "$work/mpi_$mode.txt")"
  cmp "$work/single_$mode.png" "$work/mpi_$mode.png" || fail "2-rank $mode render differs from the single process's"
done
# The summary counts the rays of both ranks: the single process's counts.
single_rays=$("$lancer" render "$scene" --size 96x72 --threads 1 -o "$work/again.png" | grep '^rays:' | cut -d';' -f1)
mpi_rays=$(grep '^rays:' "$work/mpi_whitted.txt" | cut -d';' -f1)
[ -n "$single_rays" ] && [ "$single_rays" = "$mpi_rays" ] || fail "ray counts: '$single_rays' against '$mpi_rays'"

# 2. A rays file: 1001 rays from points around the mesh's centre (not a multiple of the rank count).
python3 - "$work/test.rays" <<'PYTHON'
import random, struct, sys
random.seed(25)
with open(sys.argv[1], "wb") as out:
    for _ in range(1001):
        origin = [random.uniform(-0.05, 0.05) for _ in range(3)]
        direction = [random.gauss(0.0, 1.0) for _ in range(3)]
        out.write(struct.pack("<8f", *origin, *direction, 0.0, float("inf")))
PYTHON
"$lancer" rays "$mesh" --rays "$work/test.rays" --hits "$work/single.hits" 2> /dev/null || fail "single-process rays"
for ranks in 2 3; do
  "${mpi[@]}" -np $ranks "$lancer" rays "$mesh" --rays "$work/test.rays" --hits "$work/mpi$ranks.hits" \
    > "$work/rays$ranks.txt" 2>&1 || fail "$ranks-rank rays: $(cat "$work/rays$ranks.txt")"
  cmp "$work/single.hits" "$work/mpi$ranks.hits" || fail "$ranks-rank hits differ from the single process's"
done

# 3. Rank 1 is given a scene it cannot read (mpirun's MPMD form): every rank stops, exit code 2, and the
# one message names rank 1.
"${mpi[@]}" -np 1 "$lancer" render "$scene" -o "$work/never.png" : \
  -np 1 "$lancer" render "$work/missing.nff" -o "$work/never.png" > "$work/failure.txt" 2>&1
code=$?
[ $code -ne 124 ] || fail "the job with a missing scene hung"
[ $code -ne 0 ] || fail "the job with a missing scene succeeded"
grep -q "loading the scene failed on rank 1 of 2" "$work/failure.txt" || fail "no message naming rank 1: $(cat "$work/failure.txt")"
[ "$(grep -c '^lancer:' "$work/failure.txt")" -eq 1 ] || fail "not one message: $(cat "$work/failure.txt")"
[ ! -e "$work/never.png" ] || fail "a picture was written"

# 4. Rank 1 runs out of memory loading the mesh (its --max-memory too small): the same, with exit code 2.
"${mpi[@]}" -np 1 "$lancer" render "$mesh" --size 32x32 -o "$work/never.png" : \
  -np 1 "$lancer" render "$mesh" --size 32x32 --max-memory 2M -o "$work/never.png" > "$work/memory.txt" 2>&1
code=$?
[ $code -eq 2 ] || fail "out of memory on rank 1: exit code $code, expected 2"
grep -q "loading the scene failed on rank 1 of 2" "$work/memory.txt" || fail "no message naming rank 1: $(cat "$work/memory.txt")"
[ "$(grep -c '^lancer:' "$work/memory.txt")" -eq 1 ] || fail "not one message: $(cat "$work/memory.txt")"

# 5. Rank 1 alone is given an option it refuses, while rank 0 goes on to load the scene and waits for it:
# the job still ends (MPI_Abort), with rank 1's message.
"${mpi[@]}" -np 1 "$lancer" render "$scene" -o "$work/never.png" : \
  -np 1 "$lancer" render "$scene" --mode nonsense -o "$work/never.png" > "$work/option.txt" 2>&1
code=$?
[ $code -ne 124 ] || fail "the job with an option refused on rank 1 hung"
[ $code -ne 0 ] || fail "the job with an option refused on rank 1 succeeded"
grep -q "lancer (rank 1): .*nonsense" "$work/option.txt" || fail "no message from rank 1: $(cat "$work/option.txt")"

if [ $failures -ne 0 ]; then
  echo "$failures failure(s)"
  exit 1
fi
echo "mpi_test: 2 and 3 ranks agree with the single process; the failure names its rank"
