#!/bin/sh
# The compiler launcher of the objects compiled for another instruction set (src/CMakeLists.txt,
# docs/isa.md, "Why the namespaces"). It runs the compile command it is given, then renames, in the object
# written, every weak code symbol whose name has no `avx512` in it: an inline function of a header shared
# with the AVX2 baseline that the compiler left out of line (clang's sanitized builds leave dozens; any
# compiler's Debug build, about 180). Renamed, it no longer competes with the baseline's copy at link time,
# so the linker cannot put AVX-512 code on the AVX2 path. Data symbols keep their names, so a static local
# of such a function stays one object. Code names are all the object exports, so the rename cannot break a
# caller outside it.
# Usage: isa_private_symbols.sh NM READELF OBJCOPY SUFFIX COMPILER ARGUMENT...
set -eu
nm_tool=$1
readelf_tool=$2
objcopy_tool=$3
suffix=$4
shift 4
"$@"

object=
previous=
for argument in "$@"; do
    if [ "$previous" = "-o" ]; then object=$argument; fi
    previous=$argument
done
if [ -z "$object" ]; then
    echo "isa_private_symbols.sh: no -o OBJECT in the compile command" >&2
    exit 1
fi

# The linker keeps one copy of each COMDAT group by its signature, which need not be the function's name:
# GCC puts a constructor's two names (C1, C2) in a group signed C5. So the signature of every group that
# holds code is renamed too; a group of data only (a static local, a typeinfo) keeps its name.
renames="$object.renames"
{
    "$nm_tool" --defined-only --extern-only "$object" | awk '$2 == "W" { print $3 }'
    "$readelf_tool" --section-groups --wide "$object" | awk '
        /^COMDAT group section/ { flush(); split($0, parts, "["); signature = parts[3];
                                  sub(/\].*/, "", signature); code = 0; next }
        $NF ~ /^\.text/ { code = 1 }
        function flush() { if (signature != "" && code) print signature; signature = "" }
        END { flush() }'
} | awk -v suffix="$suffix" '$1 !~ /avx512/ && !seen[$1]++ { print $1, $1 suffix }' > "$renames"
if [ -s "$renames" ]; then
    "$objcopy_tool" --redefine-syms="$renames" "$object"
fi
rm -f "$renames"
