// The instruction sets of lancer's SIMD kernels. The library's baseline is AVX2 (x86-64-v3); the kernels
// that gain from 16 lanes are compiled for AVX-512 (x86-64-v4) too, and a structure picks one when it is
// built, the widest this CPU runs unless BuildOptions::isa (`--set simd.isa=...`) asks for another, as
// Embree's device does. docs/isa.md has the design note.
#pragma once

#include <string_view>
#include <vector>

namespace lancer {

enum class SimdIsa {
    Auto,    // the widest available
    Avx2,    // 8 float lanes
    Avx512,  // 16 float lanes (AVX-512 F, CD, BW, DQ, VL: x86-64-v4)
};

// Whether this build has kernels for `isa` and this CPU runs them; Auto always is.
[[nodiscard]] bool isa_available(SimdIsa isa);
// The available instruction sets other than Auto, narrowest first (empty in a build without AVX2).
[[nodiscard]] std::vector<SimdIsa> available_isas();
// "auto", "avx2", "avx512".
[[nodiscard]] std::string_view isa_name(SimdIsa isa);
// `isa`, or the widest available for Auto. Throws std::invalid_argument, naming the instruction set and what
// is available, when it is not available.
[[nodiscard]] SimdIsa resolve_isa(SimdIsa isa);

}  // namespace lancer
