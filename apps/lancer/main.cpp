// lancer: the command-line front end. Exit codes: 0 success, 2 bad input (file, flag), 1 a failed check
// (structures that disagree in the bench) or an internal error.
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <new>
#include <utility>

#include "commands.hpp"
#include "common.hpp"
#include "distributed.hpp"
#include "lancer/io.hpp"

namespace {

// Under mpirun every rank meets the same errors (each parses the same arguments; the failures of loading,
// building and rendering are agreed on by every rank, lancer::cli::Job), so rank 0 alone says why.
template <class... Args>
void report(fmt::format_string<Args...> format, Args&&... args) {
    if (lancer::cli::Job::get().is_root()) fmt::print(stderr, format, std::forward<Args>(args)...);
}

}  // namespace

int main(int argc, char** argv) {
    static_cast<void>(lancer::cli::Job::get());  // MPI starts here under mpirun
    CLI::App app{
        "lancer: ray-tracing kernels (Pluecker-connected octree, BVH, kd-tree, grid) and a renderer"};
    app.require_subcommand(1);
    lancer::cli::add_render_command(app);
    lancer::cli::add_info_command(app);
    lancer::cli::add_rays_command(app);
    lancer::cli::add_stats_command(app);
    lancer::cli::add_bench_command(app);
    lancer::cli::add_convert_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& error) {
        if (!lancer::cli::Job::get().is_root()) return error.get_exit_code() == 0 ? 0 : 2;
        const int code = app.exit(error);
        return code == 0 ? 0 : 2;
    } catch (const lancer::cli::JobError& error) {
        report("lancer: {}\n", error.what());
        return error.exit_code();
    } catch (const lancer::LoadError& error) {
        report("lancer: {}\n", error.what());
        return 2;
    } catch (const lancer::cli::InputError& error) {
        report("lancer: {}\n", error.what());
        return 2;
    } catch (const std::bad_alloc&) {
        // Past loading and building (which say which phase failed): rays, images, the bench's records.
        report("lancer: {}\n", lancer::cli::out_of_memory("the command", "running").what());
        return 2;
    } catch (const lancer::cli::CheckFailure& error) {
        report("lancer: {}\n", error.what());
        return 1;
    } catch (const std::exception& error) {
        // Not agreed on by the ranks: each says it, with its rank under mpirun.
        const lancer::cli::Job& job = lancer::cli::Job::get();
        fmt::print(stderr, "lancer{}: internal error: {}\n",
                   job.distributed() ? fmt::format(" (rank {})", job.rank()) : std::string(), error.what());
        return 1;
    }
    return 0;
}
