#include "bench_report.hpp"

#include <fmt/core.h>
#include <fmt/os.h>

#include <algorithm>
#include <array>
#include <system_error>

#include "common.hpp"
#include "lancer/views.hpp"

namespace lancer::cli {

std::string_view view_name(BenchView view) {
    switch (view) {
        case BenchView::Primary:
            return "primary";
        case BenchView::Diffuse:
            return secondary_view_name(SecondaryView::Diffuse);
        case BenchView::Shadow:
            return secondary_view_name(SecondaryView::Shadow);
    }
    return "";
}

void write_bench_json(const std::string& file, const std::vector<BenchRecord>& records) {
    std::string json = "[\n";
    for (std::size_t i = 0; i < records.size(); ++i) {
        const BenchRecord& r = records[i];
        json += fmt::format(
            "  {{\"mesh\": \"{}\", \"view\": \"{}\", \"triangles\": {}, \"accel\": \"{}\", \"threads\": {}, "
            "\"build_ms\": "
            "{:.3f}, "
            "\"memory_bytes\": {}, \"geometry_bytes\": {}, \"mrays_per_s\": {:.4f}, \"mrays_min\": {:.4f}, "
            "\"mrays_max\": {:.4f}, \"hit_fraction\": {:.6f}, \"nodes_per_ray\": {}, \"prims_per_ray\": "
            "{}, \"mismatches\": {}}}{}\n",
            r.mesh, view_name(r.view), r.triangles, r.accel, r.threads, r.build_ms, r.memory_bytes,
            r.geometry_bytes, r.mrays_median, r.mrays_min, r.mrays_max, r.hit_fraction,
            r.counted ? fmt::format("{:.4f}", r.nodes_per_ray) : "null",
            r.counted ? fmt::format("{:.4f}", r.prims_per_ray) : "null", r.mismatches,
            i + 1 < records.size() ? "," : "");
    }
    json += "]\n";
    try {
        fmt::output_file(file).print("{}", json);
    } catch (const std::system_error& error) {
        throw InputError(file + ": " + error.what());
    }
}

void write_bench_svg(const std::string& file, const std::vector<BenchRecord>& records) {
    constexpr int kBarHeight = 16, kLabelWidth = 230, kChartWidth = 520, kGroupGap = 28;
    double best = 0.0;
    for (const BenchRecord& r : records)
        best = std::max(best, r.mrays_median);
    const std::array<const char*, 6> palette = {"#4c72b0", "#dd8452", "#55a868",
                                                "#c44e52", "#8172b3", "#937860"};
    std::vector<std::string> accels;
    for (const BenchRecord& r : records) {
        if (std::find(accels.begin(), accels.end(), r.accel) == accels.end()) accels.push_back(r.accel);
    }
    std::string body;
    int y = 40;
    std::string current_mesh;
    for (const BenchRecord& r : records) {
        if (r.mesh != current_mesh) {
            current_mesh = r.mesh;
            y += kGroupGap / 2;
            body += fmt::format("<text x=\"8\" y=\"{}\" font-weight=\"bold\">{} ({} triangles)</text>\n", y,
                                r.mesh, r.triangles);
            y += 8;
        }
        const auto colour =
            static_cast<std::size_t>(std::find(accels.begin(), accels.end(), r.accel) - accels.begin());
        const double width = best > 0.0 ? kChartWidth * r.mrays_median / best : 0.0;
        body += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}{}, {} thread{}</text>\n",
                            kLabelWidth - 6, y + kBarHeight - 4, r.accel,
                            r.view == BenchView::Primary ? "" : fmt::format(", {}", view_name(r.view)),
                            r.threads, r.threads > 1 ? "s" : "");
        body += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{:.1f}\" height=\"{}\" fill=\"{}\"/>\n",
                            kLabelWidth, y, width, kBarHeight - 2, palette[colour % palette.size()]);
        body += fmt::format("<text x=\"{:.1f}\" y=\"{}\">{:.2f}</text>\n", kLabelWidth + width + 4,
                            y + kBarHeight - 4, r.mrays_median);
        y += kBarHeight;
    }
    const int height = y + 20;
    const std::string svg = fmt::format(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" "
        "font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
        "<text x=\"8\" y=\"20\" font-size=\"14\">lancer bench: Mrays/s on the views of VIEWS.md (median of "
        "the "
        "frames)</text>\n{}</svg>\n",
        kLabelWidth + kChartWidth + 80, height, body);
    try {
        fmt::output_file(file).print("{}", svg);
    } catch (const std::system_error& error) {
        throw InputError(file + ": " + error.what());
    }
}

}  // namespace lancer::cli
