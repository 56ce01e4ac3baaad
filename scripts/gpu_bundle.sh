#!/usr/bin/env bash
# scripts/gpu_bundle.sh [DIR]: builds the CUDA path in build-gpu/ and packs what a GPU machine without the
# project's Debian libraries needs to run its checks (docs/cuda.md, "Running it on the lent GPU"):
#   - build-gpu/: lancer, cuda_gpu_tests, cuda_port_tests and cli_tests, for any x86-64-v3 host (not
#     -march=native: the GPU machine's CPU is another), without Embree (its library alone is 44 MB);
#   - DIR/lib: the shared libraries those binaries load, except the C and C++ runtimes the machine has;
#   - DIR/data: the Stanford meshes of ../shared/data/meshes, xz-compressed (7 MB instead of 22);
#   - DIR/run_checks.sh: run there, from the repository root: the GPU tests, the CLI's byte-for-byte
#     test and `lancer bench --device cuda` with both triangle tests, logs to $OUT (or /tmp).
# DIR (default .gpu) must be ignored by git (.git/info/exclude), so that nothing here is committed; carry it
# and the four binaries to the machine. Exits 2 on bad input.
set -euo pipefail
cd "$(dirname "$0")/.."

bundle=${1:-.gpu}
meshes=../shared/data/meshes
[[ $# -le 1 ]] || { echo "usage: scripts/gpu_bundle.sh [DIR]" >&2; exit 2; }
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
mkdir -p "$bundle/lib" "$bundle/data/meshes"
# The libraries by their loaded names; the C and C++ runtimes stay the machine's (newer ones serve).
ldd "${binaries[@]}" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u |
    grep -vE '/(libc|libm|libgcc_s|libstdc\+\+|libpthread|libdl|librt)\.so' |
    while read -r library; do cp -L "$library" "$bundle/lib/"; done
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
mkdir -p "$(dirname "$PWD")"
[[ -e "$PWD" ]] || ln -s "\$root" "$PWD"
mkdir -p "$(dirname "$PWD")/shared"
[[ -e "$(dirname "$PWD")/shared/data" ]] || ln -s "\$root/$bundle/data" "$(dirname "$PWD")/shared/data"
for mesh in "\$root/$bundle"/data/meshes/*.xz; do [[ -e \${mesh%.xz} ]] || xz -dk "\$mesh"; done
export LD_LIBRARY_PATH=\$root/$bundle/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}
cd "$PWD"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
build-gpu/tests/cuda/cuda_port_tests >"\$out/port_tests.log" 2>&1; tail -1 "\$out/port_tests.log"
build-gpu/tests/cuda/cuda_gpu_tests >"\$out/gpu_tests.log" 2>&1; tail -3 "\$out/gpu_tests.log"
build-gpu/tests/apps/cli_tests --gtest_filter='*Cuda*' 2>&1 | tail -1
for test in "" --moller-trumbore; do
    build-gpu/apps/lancer/lancer bench --device cuda --frames 20 \$test 2>&1 | tee -a "\$out/bench.log"
done
EOF
chmod +x "$bundle/run_checks.sh"
du -sh "$bundle" "${binaries[@]}"
echo "carry: $bundle ${binaries[*]}; run there: bash $bundle/run_checks.sh"
