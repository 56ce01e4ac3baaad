#include "lancer/isa.hpp"

#include <stdexcept>
#include <string>

namespace lancer {
namespace {

bool cpu_runs_avx512() {
#if LANCER_HAS_AVX512_KERNELS
    // x86-64-v4, the -march of lancer_kernels_avx512. GCC's check includes the operating system's support of
    // the AVX-512 registers (XGETBV).
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
           __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
           __builtin_cpu_supports("avx512vl");
#else
    return false;
#endif
}

}  // namespace

bool isa_available(SimdIsa isa) {
    switch (isa) {
        case SimdIsa::Auto:
            return true;
        case SimdIsa::Avx2:
#if defined(__AVX2__)
            return true;
#else
            return false;
#endif
        case SimdIsa::Avx512: {
            static const bool runs = cpu_runs_avx512();
            return runs;
        }
    }
    return false;
}

std::vector<SimdIsa> available_isas() {
    std::vector<SimdIsa> isas;
    for (SimdIsa isa : {SimdIsa::Avx2, SimdIsa::Avx512}) {
        if (isa_available(isa)) isas.push_back(isa);
    }
    return isas;
}

std::string_view isa_name(SimdIsa isa) {
    switch (isa) {
        case SimdIsa::Auto:
            return "auto";
        case SimdIsa::Avx2:
            return "avx2";
        case SimdIsa::Avx512:
            return "avx512";
    }
    return "unknown";
}

SimdIsa resolve_isa(SimdIsa isa) {
    const std::vector<SimdIsa> available = available_isas();
    if (isa == SimdIsa::Auto) {
        if (available.empty()) throw std::invalid_argument("no SIMD kernels in this build (it lacks AVX2)");
        return available.back();
    }
    if (isa_available(isa)) return isa;
    std::string names;
    for (SimdIsa other : available)
        names += (names.empty() ? "" : ", ") + std::string(isa_name(other));
    throw std::invalid_argument("instruction set " + std::string(isa_name(isa)) +
                                ": this build and CPU run " + (names.empty() ? "none" : names));
}

}  // namespace lancer
