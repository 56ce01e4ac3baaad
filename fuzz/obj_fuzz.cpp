// libFuzzer harness: OBJ through assimp (src/scene/assimp_loader.cpp) on arbitrary bytes. Findings inside
// assimp itself are recorded in docs/robustness.md and guarded in the wrapper where they can be.
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer::fuzz;
    load_and_check(write_scratch_file("input.obj", as_text(data, size)));
    return 0;
}
