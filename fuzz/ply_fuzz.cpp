// libFuzzer harness: the PLY reader (src/scene/ply_loader.cpp), ascii and binary, on arbitrary bytes.
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer::fuzz;
    load_and_check(write_scratch_file("input.ply", as_text(data, size)));
    return 0;
}
