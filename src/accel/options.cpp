// `--set KEY=VALUE`: structure options from the command line, checked and with the accepted range in the
// error message.
#include "accel/options.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "lancer/isa.hpp"

namespace lancer {

void fail_option(std::string_view key, std::string_view value, std::string_view expected) {
    throw std::invalid_argument("--set " + std::string(key) + "=" + std::string(value) + ": expected " +
                                std::string(expected));
}

// The accepted values as listed, whatever this CPU runs; a request for more than it runs fails here, not at
// the build.
std::vector<BuildOptionRow> shared_option_rows() {
    return {
        {"simd.isa",
         "the instruction set of bvh8_packet's kernels, of those this build and CPU run; auto: the widest",
         "auto, avx2, avx512", [](const BuildOptions& o) { return std::string(isa_name(o.isa)); },
         [](BuildOptions& o, std::string_view value) {
             for (SimdIsa isa : {SimdIsa::Auto, SimdIsa::Avx2, SimdIsa::Avx512}) {
                 if (value == isa_name(isa) && isa_available(isa)) {
                     o.isa = isa;
                     return;
                 }
             }
             std::string accepted = "auto";
             for (SimdIsa isa : available_isas())
                 accepted += ", " + std::string(isa_name(isa));
             fail_option("simd.isa", value,
                         "one of " + accepted + " (the instruction sets this build and CPU run)");
         }}};
}

namespace {

std::string known_keys(const std::vector<BuildOptionRow>& rows) {
    std::string known;
    for (const BuildOptionRow& each : rows)
        known.append(known.empty() ? "" : ", ").append(each.key);
    return known;
}

}  // namespace

void set_build_option(BuildOptions& options, std::string_view assignment) {
    const auto equals = assignment.find('=');
    const std::string_view key = assignment.substr(0, equals);
    const std::vector<BuildOptionRow> rows = option_rows();
    const auto row =
        std::find_if(rows.begin(), rows.end(), [&](const BuildOptionRow& r) { return r.key == key; });
    if (equals == std::string_view::npos || row == rows.end()) {
        throw std::invalid_argument("--set " + std::string(assignment) +
                                    ": expected KEY=VALUE with KEY one of " + known_keys(rows));
    }
    row->set(options, assignment.substr(equals + 1));
}

std::string build_option_value(const BuildOptions& options, std::string_view key) {
    const std::vector<BuildOptionRow> rows = option_rows();
    const auto row =
        std::find_if(rows.begin(), rows.end(), [&](const BuildOptionRow& r) { return r.key == key; });
    if (row == rows.end())
        throw std::invalid_argument("unknown option " + std::string(key) + " (known: " + known_keys(rows) +
                                    ")");
    return row->show(options);
}

std::vector<BuildOptionInfo> build_option_infos() {
    const BuildOptions defaults;
    std::vector<BuildOptionInfo> infos;
    for (const BuildOptionRow& row : option_rows())
        infos.push_back({row.key, row.accepted, row.show(defaults), row.help});
    return infos;
}

}  // namespace lancer
