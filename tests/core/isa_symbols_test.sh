#!/bin/sh
# The objects compiled for AVX-512 define code only under names of their own: in lancer::avx512, or a
# template on its types (lancer::simd::avx512::Avx512) (core/isa_namespace.hpp), or, for a header function
# the compiler left out of line, its name with the suffix .avx512 its launcher gave it
# (cmake/isa_private_symbols.sh). A function they define under another name would compete with the AVX2
# baseline's copy at link time, and the linker's choice could put AVX-512 instructions on the AVX2 path.
# The same holds for the COMDAT groups that hold code, which the linker keeps one of by signature: a group
# under a shared signature would be dropped for the baseline's, leaving the kernel's renamed calls unbound.
# Usage: isa_symbols_test.sh OBJECT...
status=0
for object in "$@"; do
    # Defined external code symbols (T, W), demangled; a name with neither avx512 mark is a failure.
    outside=$(nm --defined-only --extern-only -C "$object" | awk '$2 == "T" || $2 == "W"' |
              cut -d' ' -f3- | grep -v -e '::avx512::' -e ' \[clone \.avx512\]$')
    count=$(nm --defined-only --extern-only "$object" | awk '$2 == "T" || $2 == "W"' | wc -l)
    # Signatures of the groups with a .text section, mangled (the suffix keeps an avx512 in them).
    shared_groups=$(readelf --section-groups --wide "$object" | awk '
        /^COMDAT group section/ { flush(); split($0, parts, "["); signature = parts[3];
                                  sub(/\].*/, "", signature); code = 0; next }
        $NF ~ /^\.text/ { code = 1 }
        function flush() { if (signature != "" && code && signature !~ /avx512/) print signature; signature = "" }
        END { flush() }')
    if [ -n "$outside" ]; then
        echo "$object: code under names the AVX2 baseline shares:"
        echo "$outside"
        status=1
    elif [ -n "$shared_groups" ]; then
        echo "$object: groups of code under signatures the AVX2 baseline shares:"
        echo "$shared_groups"
        status=1
    elif [ "$count" -eq 0 ]; then
        echo "$object: no code symbol at all (nothing to check; was it built?)"
        status=1
    else
        echo "$object: $count code symbols, all under avx512 names, and their groups too"
    fi
done
exit $status
