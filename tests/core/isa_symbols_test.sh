#!/bin/sh
# The objects compiled for AVX-512 define code only under names of their own (core/isa_namespace.hpp):
# in lancer::avx512, or a template on its types (lancer::simd::avx512::Avx512). A function they define
# under another name, an inline function of a header shared with the AVX2 baseline, would compete with the
# baseline's copy at link time, and the linker's choice could put AVX-512 instructions on the AVX2 path.
# Usage: isa_symbols_test.sh OBJECT...
status=0
for object in "$@"; do
    # Defined external code symbols (T, W), demangled; a name without an avx512 namespace is a failure.
    outside=$(nm --defined-only --extern-only -C "$object" | awk '$2 == "T" || $2 == "W"' |
              cut -d' ' -f3- | grep -v '::avx512::')
    count=$(nm --defined-only --extern-only "$object" | awk '$2 == "T" || $2 == "W"' | wc -l)
    if [ -n "$outside" ]; then
        echo "$object: code under names the AVX2 baseline shares:"
        echo "$outside"
        status=1
    elif [ "$count" -eq 0 ]; then
        echo "$object: no code symbol at all (nothing to check; was it built?)"
        status=1
    else
        echo "$object: $count code symbols, all under avx512 names"
    fi
done
exit $status
