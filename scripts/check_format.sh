#!/usr/bin/env bash
# scripts/check_format.sh: checks every tracked C, C++ and CUDA source against .clang-format (clang-format
# --dry-run -Werror), prints the files that differ and exits 1 if any does; `clang-format -i FILE` fixes one.
# CI runs it before the tests (.ci/run), so that formatting is never a reviewer's job.
set -euo pipefail
cd "$(dirname "$0")/.."

CLANG_FORMAT=${CLANG_FORMAT:-clang-format}
if ! command -v "$CLANG_FORMAT" >/dev/null; then
    echo "check_format.sh: $CLANG_FORMAT not found (scripts/deps.sh installs it)" >&2
    exit 2
fi

mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.cu' '*.cuh' '*.h')
unformatted=()
for file in "${files[@]}"; do
    if ! "$CLANG_FORMAT" --dry-run -Werror "$file" >/dev/null 2>&1; then unformatted+=("$file"); fi
done

if ((${#unformatted[@]} > 0)); then
    echo "check_format.sh: ${#unformatted[@]} of ${#files[@]} files differ from .clang-format:" >&2
    printf '  %s\n' "${unformatted[@]}" >&2
    exit 1
fi
echo "check_format.sh: ${#files[@]} files formatted"
