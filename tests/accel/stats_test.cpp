// Each structure names and explains its own figures (AccelStats): the keys `lancer stats`, its JSON and the
// Python module's stats() print, so that each must be unique, snake_case and explained, and a count whole.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>

#include "lancer/accel.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

bool is_snake_case(const std::string& key) {
    if (key.empty() || key.front() == '_' || key.back() == '_') return false;
    for (const char c : key) {
        if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
    }
    return true;
}

TEST(AccelFigures, EveryStructureNamesAndExplainsItsOwn) {
    const std::vector<Triangle> triangles = testing::knot_triangles(40);
    const Geometry geometry{triangles, {}};
    for (const std::string_view name : accel_names()) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(geometry, BuildOptions{});
        const AccelStats stats = accel->stats();
        EXPECT_EQ(stats.primitives, triangles.size()) << name;
        std::set<std::string> keys;
        for (const AccelFigure& figure : stats.figures) {
            EXPECT_TRUE(keys.insert(figure.key).second) << name << ": " << figure.key << " twice";
            EXPECT_TRUE(is_snake_case(figure.key)) << name << ": '" << figure.key << "'";
            EXPECT_FALSE(figure.help.empty()) << name << ": " << figure.key;
            EXPECT_TRUE(std::isfinite(figure.value)) << name << ": " << figure.key;
            if (figure.whole) {
                EXPECT_GE(figure.value, 0.0) << name << ": " << figure.key;
                EXPECT_EQ(figure.value, std::floor(figure.value)) << name << ": " << figure.key;
                EXPECT_EQ(static_cast<double>(stats.count(figure.key)), figure.value) << name;
            }
            EXPECT_EQ(stats.find(figure.key), &figure) << name;
        }
        // What each kind of structure has, and what it does not claim to have.
        const bool tree = name != "brute" && name != "grid" && !name.starts_with("embree");
        for (const char* key : {"nodes", "leaves", "empty_leaves", "max_depth", "mean_depth",
                                "mean_refs_per_leaf", "max_refs_per_leaf"})
            EXPECT_EQ(stats.find(key) != nullptr, tree) << name << ": " << key;
        const bool grid = name == "grid";
        for (const char* key : {"cells", "empty_cells", "mean_refs_per_cell", "max_refs_per_cell"})
            EXPECT_EQ(stats.find(key) != nullptr, grid) << name << ": " << key;
        if (tree) {
            EXPECT_GT(stats.count("leaves"), 1u) << name;
        }
        if (tree || grid) {
            EXPECT_GE(stats.count("references"), triangles.size()) << name;
            EXPECT_GT(stats.value("sah_cost"), 0.0) << name;
        }
        EXPECT_EQ(stats.find("sah_ratio") != nullptr, name.starts_with("bvh")) << name;
        if (name.starts_with("embree")) {
            EXPECT_TRUE(stats.figures.empty()) << name;
        }
    }
}

TEST(AccelFigures, AnUnknownKeyOrACountOfAValueIsRefusedByName) {
    AccelStats stats;
    stats.figures = {{"leaves", 3.0, true, "leaves"}};
    EXPECT_EQ(stats.count("leaves"), 3u);
    EXPECT_EQ(stats.find("nodes"), nullptr);
    try {
        static_cast<void>(stats.value("nodes"));
        FAIL() << "an unknown figure was read";
    } catch (const std::out_of_range& error) {
        EXPECT_NE(std::string(error.what()).find("'nodes'"), std::string::npos) << error.what();
    }
    EXPECT_THROW(static_cast<void>(stats.count("nodes")), std::out_of_range);
    stats.figures.push_back({"mean_depth", 2.5, false, "mean depth of the leaves"});
    EXPECT_EQ(stats.value("mean_depth"), 2.5);
    EXPECT_THROW(static_cast<void>(stats.count("mean_depth")), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
