// The progress line: its format, silence when disabled, rate limiting, and counting from many threads.
#include "render/progress.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace lancer {
namespace {

TEST(ProgressLine, ShowsPercentCountsElapsedAndEta) {
    // 1234 of 4096 in 1.3 s: 30% (rounded down), ETA 1.3 * 2862 / 1234 = 3.02 s.
    EXPECT_EQ(progress_line("render", "tiles", 1234, 4096, 1.3, true),
              "render  30% (1234/4096 tiles) 1.3 s, ETA 3.0 s");
}

TEST(ProgressLine, ReachesHundredOnlyWhenDone) {
    EXPECT_EQ(progress_line("build", "nodes", 999, 1000, 2.0, false), "build  99% (999/1000 nodes) 2.0 s");
    EXPECT_EQ(progress_line("render", "tiles", 4096, 4096, 3.14, false),
              "render 100% (4096/4096 tiles) 3.1 s");
}

TEST(ProgressLine, EmptyJobIsDoneAndNoWorkHasNoEta) {
    EXPECT_EQ(progress_line("bench", "runs", 0, 0, 0.0, true), "bench 100% (0/0 runs) 0.0 s");
}

TEST(ProgressReporter, DisabledPrintsNothing) {
    testing::internal::CaptureStderr();
    {
        // Past the print interval, where an enabled reporter would print.
        ProgressReporter progress("render", 2, "tiles", false);
        progress.advance();
        std::this_thread::sleep_for(std::chrono::milliseconds(120));
        progress.advance();
        progress.finish();
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(ProgressReporter, FinishEndsTheLineOnce) {
    testing::internal::CaptureStderr();
    {
        ProgressReporter progress("render", 4, "tiles", true);
        for (int i = 0; i < 4; ++i)
            progress.advance();
        progress.finish();
        progress.finish();
        progress.advance();  // after the end: nothing more on screen
    }
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(std::regex_match(output, std::regex("\rrender 100% \\(4/4 tiles\\) [0-9]+\\.[0-9] s\n")))
        << output;
}

TEST(ProgressReporter, DestructorEndsAnAbandonedLine) {
    testing::internal::CaptureStderr();
    { ProgressReporter("render", 4, "tiles", true).advance(); }
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(std::regex_match(output, std::regex("\rrender  25% \\(1/4 tiles\\) [0-9]+\\.[0-9] s\n")))
        << output;
}

TEST(ProgressReporter, PrintsAtMostTenTimesASecond) {
    testing::internal::CaptureStderr();
    {
        // Thousands of advances in far less than 100 ms: only the final line, plus one more if the machine
        // stalled this thread past the first interval.
        ProgressReporter progress("render", 5000, "tiles", true);
        for (int i = 0; i < 5000; ++i)
            progress.advance();
    }
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_LE(std::count(output.begin(), output.end(), '\r'), 2) << output;
}

TEST(ProgressReporter, RewritesTheLineAfterTheInterval) {
    testing::internal::CaptureStderr();
    {
        ProgressReporter progress("render", 3, "tiles", true);
        progress.advance();
        std::this_thread::sleep_for(std::chrono::milliseconds(120));
        progress.advance();
    }
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_NE(output.find("\rrender  66% (2/3 tiles) "), std::string::npos) << output;
    EXPECT_NE(output.find(", ETA "), std::string::npos) << output;
    EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
}

TEST(ProgressReporter, CountsFromManyThreads) {
    testing::internal::CaptureStderr();
    {
        ProgressReporter progress("render", 4000, "tiles", true);
        std::vector<std::thread> workers;
        for (int t = 0; t < 4; ++t) {
            workers.emplace_back([&progress] {
                for (int i = 0; i < 1000; ++i)
                    progress.advance();
            });
        }
        for (std::thread& worker : workers)
            worker.join();
    }
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_NE(output.find("render 100% (4000/4000 tiles)"), std::string::npos) << output;
}

}  // namespace
}  // namespace lancer
