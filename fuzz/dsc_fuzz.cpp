// libFuzzer harness: the DSC reader (src/scene/dsc_loader.cpp) with the OFF it names. The input is the
// .dsc, a NUL byte, then the .off of the same stem beside it (scripts/fuzz.sh builds the seeds so); an
// input without a NUL byte is a .dsc whose .off is missing.
#include <filesystem>
#include <string_view>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer::fuzz;
    const std::string_view input = as_text(data, size);
    const std::size_t separator = input.find('\0');
    const std::filesystem::path off = scratch_dir() / "scene.off";
    if (separator == std::string_view::npos) {
        std::filesystem::remove(off);
    } else {
        (void)write_scratch_file("scene.off", input.substr(separator + 1));
    }
    load_and_check(write_scratch_file("scene.dsc", input.substr(0, separator)));
    return 0;
}
