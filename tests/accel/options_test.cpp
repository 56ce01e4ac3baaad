// The `--set` keys come from the registry: each registered structure's option group, once, then the shared
// keys. Every key reads back what was set, and BuildOptions copies its groups.
#include <gtest/gtest.h>

#include <set>
#include <stdexcept>
#include <string>

#include "accel/bvh/bvh.hpp"
#include "accel/plucker/plucker.hpp"
#include "lancer/accel.hpp"

namespace lancer {
namespace {

TEST(BuildOptionKeys, AreListedOnceEachAndReadBackTheirDefaults) {
    const BuildOptions defaults;
    std::set<std::string> keys;
    for (const BuildOptionInfo& info : build_option_infos()) {
        EXPECT_TRUE(keys.insert(info.key).second) << info.key << " is listed twice";
        EXPECT_EQ(build_option_value(defaults, info.key), info.default_value) << info.key;
        BuildOptions options;
        set_build_option(options, info.key + "=" + info.default_value);
        EXPECT_EQ(build_option_value(options, info.key), info.default_value) << info.key;
    }
    // The groups of the structures that have options, and the shared key.
    for (const char* key :
         {"grid.density", "octree.leaf_size", "plucker.balanced", "kdtree.cost", "bvh.builder", "simd.isa"})
        EXPECT_TRUE(keys.count(key)) << key;
}

TEST(BuildOptionKeys, SetTheirStructuresGroup) {
    BuildOptions options;
    set_build_option(options, "bvh.max_leaf_size=9");
    set_build_option(options, "plucker.stored_boxes=false");
    EXPECT_EQ(options.group<BvhOptions>().max_leaf_size, 9);
    EXPECT_FALSE(options.group<PluckerOptions>().stored_boxes);
    EXPECT_EQ(build_option_value(options, "bvh.max_leaf_size"), "9");
    // A copy is a copy: setting it leaves the original as it was.
    BuildOptions copy = options;
    copy.group<BvhOptions>().max_leaf_size = 2;
    EXPECT_EQ(options.group<BvhOptions>().max_leaf_size, 9);
    EXPECT_EQ(copy.group<BvhOptions>().max_leaf_size, 2);
    // An untouched group reads as its defaults, also through a const BuildOptions.
    const BuildOptions untouched;
    EXPECT_EQ(untouched.group<BvhOptions>().max_leaf_size, BvhOptions{}.max_leaf_size);
}

TEST(BuildOptionKeys, RefuseUnknownKeysAndValuesWithTheAcceptedOnes) {
    BuildOptions options;
    try {
        set_build_option(options, "bvh.bins=1");
        FAIL() << "bvh.bins=1 was accepted";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("a number in [2, 256]"), std::string::npos) << error.what();
    }
    EXPECT_THROW(set_build_option(options, "bvh.no_such_key=1"), std::invalid_argument);
    EXPECT_THROW(set_build_option(options, "bvh.bins"), std::invalid_argument);
    EXPECT_THROW(static_cast<void>(build_option_value(options, "no.such_key")), std::invalid_argument);
    EXPECT_EQ(options.group<BvhOptions>().bins, BvhOptions{}.bins);
}

}  // namespace
}  // namespace lancer
