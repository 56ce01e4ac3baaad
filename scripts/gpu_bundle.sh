#!/usr/bin/env bash
# scripts/gpu_bundle.sh [DIR] [BASELINE]: builds the CUDA path in build-gpu/ and packs what a GPU machine
# without the project's Debian libraries needs to run its checks (docs/cuda.md, "Running it on the lent GPU"):
#   - DIR/bundle.tar.xz: build-gpu's lancer, cuda_gpu_tests, cuda_port_tests and cli_tests, for any
#     x86-64-v3 host (not -march=native: the GPU machine's CPU is another), without Embree (its library alone
#     is 44 MB), and in gpu-lib/ the shared libraries they load, except the C and C++ runtimes the machine
#     has; BASELINE, a lancer binary built the same way (say, of the previous commit), goes in as
#     build-gpu/apps/lancer/lancer_baseline for before/after runs in one call;
#   - DIR/data: the Stanford meshes of ../shared/data/meshes, xz-compressed (7 MB instead of 22);
#   - DIR/run_checks.sh: run there, from the repository root: unpacks, runs the GPU tests, the CLI's
#     byte-for-byte test and `lancer bench --device cuda` on the three views with both triangle tests, logs to
#     $OUT (or /tmp).
# The tool carries at most 64 MiB: packed, the whole is about 20 MB. DIR (default .gpu) must be ignored by git
# (.git/info/exclude), so that nothing here is committed; carry it alone. Exits 2 on bad input.
set -euo pipefail
cd "$(dirname "$0")/.."

bundle=${1:-.gpu}
baseline=${2:-}
meshes=../shared/data/meshes
[[ $# -le 2 ]] || { echo "usage: scripts/gpu_bundle.sh [DIR] [BASELINE]" >&2; exit 2; }
[[ -z $baseline || -x $baseline ]] || { echo "gpu_bundle: $baseline is not an executable" >&2; exit 2; }
[[ -d $meshes ]] || { echo "gpu_bundle: $meshes is absent (see README, 'The Stanford meshes')" >&2; exit 2; }
if ! git check-ignore -q "$bundle/"; then
    echo "gpu_bundle: $bundle is not ignored by git: add '/$bundle/' to .git/info/exclude" >&2
    exit 2
fi

binaries=(build-gpu/apps/lancer/lancer build-gpu/tests/cuda/cuda_gpu_tests build-gpu/tests/cuda/cuda_port_tests
          build-gpu/tests/apps/cli_tests)
cmake -S . -B build-gpu -DCMAKE_BUILD_TYPE=Release -DLANCER_CUDA=ON -DLANCER_EMBREE=OFF -DLANCER_NATIVE=OFF \
      -DCMAKE_CXX_FLAGS=-march=x86-64-v3 -DLANCER_BUILD_BENCH=OFF -DLANCER_WARNINGS_AS_ERRORS=ON >/dev/null
cmake --build build-gpu -j "$(nproc)" --target lancer_cli cuda_gpu_tests cuda_port_tests cli_tests

rm -rf "$bundle"
mkdir -p "$bundle/data/meshes"
staging=$(mktemp -d)
trap 'rm -rf "$staging"' EXIT
mkdir -p "$staging/gpu-lib"
for binary in "${binaries[@]}"; do
    mkdir -p "$staging/$(dirname "$binary")"
    cp "$binary" "$staging/$binary"
done
[[ -z $baseline ]] || cp "$baseline" "$staging/build-gpu/apps/lancer/lancer_baseline"
# The libraries by their loaded names; the C and C++ runtimes stay the machine's (newer ones serve).
ldd "${binaries[@]}" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u |
    grep -vE '/(libc|libm|libgcc_s|libstdc\+\+|libpthread|libdl|librt)\.so' |
    while read -r library; do cp -L "$library" "$staging/gpu-lib/"; done
tar -C "$staging" -cf - . | xz -T0 -6 >"$bundle/bundle.tar.xz"
for mesh in bunny.obj armadillo.off dragon.ply; do
    xz -T0 -6 -c "$meshes/$mesh" >"$bundle/data/meshes/$mesh.xz"
done

# The tests' paths are compiled in (LANCER_SHARED_DIR, the CLI's path): links make them hold there.
cat >"$bundle/run_checks.sh" <<EOF
#!/usr/bin/env bash
# Made by scripts/gpu_bundle.sh: run from the repository root on the GPU machine.
set -uo pipefail
root=\$PWD
out=\${OUT:-/tmp}
tar -C "\$root" -xJf "\$root/$bundle/bundle.tar.xz"
mkdir -p "$(dirname "$PWD")"
[[ -e "$PWD" ]] || ln -s "\$root" "$PWD"
mkdir -p "$(dirname "$PWD")/shared"
[[ -e "$(dirname "$PWD")/shared/data" ]] || ln -s "\$root/$bundle/data" "$(dirname "$PWD")/shared/data"
for mesh in "\$root/$bundle"/data/meshes/*.xz; do [[ -e \${mesh%.xz} ]] || xz -dk "\$mesh"; done
export LD_LIBRARY_PATH=\$root/gpu-lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}
cd "$PWD"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
build-gpu/tests/cuda/cuda_port_tests >"\$out/port_tests.log" 2>&1; tail -1 "\$out/port_tests.log"
build-gpu/tests/cuda/cuda_gpu_tests >"\$out/gpu_tests.log" 2>&1; tail -3 "\$out/gpu_tests.log"
build-gpu/tests/apps/cli_tests --gtest_filter='*Cuda*' 2>&1 | tail -1
for test in "" --moller-trumbore; do
    build-gpu/apps/lancer/lancer bench --device cuda --view primary,diffuse,shadow --frames 20 \$test 2>&1 |
        tee -a "\$out/bench.log"
done
EOF
chmod +x "$bundle/run_checks.sh"
du -sh "$bundle"
echo "carry: $bundle; run there: bash $bundle/run_checks.sh"
