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
#include "lancer/load_scene.hpp"

namespace {

// The exit of a failed command. Under mpirun a failure that every rank agreed on (a JobError: loading,
// building, rendering, tracing; lancer::cli::Job) is printed by rank 0 alone, and every rank returns its
// code. Any other failure may be this rank's alone (an option only it was given, in mpirun's MPMD form),
// while the others wait for it in a collective call: it is printed with the rank, and the whole job ends at
// once (MPI_Abort) so that none of them hangs.
template <class... Args>
int fail(int code, fmt::format_string<Args...> format, Args&&... args) {
    const lancer::cli::Job& job = lancer::cli::Job::get();
    if (!job.distributed()) {
        fmt::print(stderr, "lancer: {}\n", fmt::format(format, std::forward<Args>(args)...));
        return code;
    }
    fmt::print(stderr, "lancer (rank {}): {}\n", job.rank(),
               fmt::format(format, std::forward<Args>(args)...));
    job.abort(code);
}

}  // namespace

int main(int argc, char** argv) {
    const lancer::cli::Job& job = lancer::cli::Job::get();  // MPI starts here under mpirun
    CLI::App app{"lancer: ray-tracing kernels (Plücker-connected octree, BVH, kd-tree, grid) and a renderer"};
    app.require_subcommand(1);
    lancer::cli::add_render_command(app);
    lancer::cli::add_info_command(app);
    lancer::cli::add_rays_command(app);
    lancer::cli::add_nearest_command(app);
    lancer::cli::add_stats_command(app);
    lancer::cli::add_bench_command(app);
    lancer::cli::add_convert_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& error) {
        if (error.get_exit_code() == 0) return job.is_root() ? app.exit(error) : 0;  // --help, on rank 0
        if (!job.distributed()) return app.exit(error) == 0 ? 0 : 2;
        return fail(2, "{}", error.what());
    } catch (const lancer::cli::JobError& error) {
        if (job.is_root()) fmt::print(stderr, "lancer: {}\n", error.what());
        return error.exit_code();
    } catch (const lancer::LoadError& error) {
        return fail(2, "{}", error.what());
    } catch (const lancer::cli::InputError& error) {
        return fail(2, "{}", error.what());
    } catch (const std::bad_alloc&) {
        // Past loading and building (which say which phase failed): rays, images, the bench's records.
        return fail(2, "{}", lancer::cli::out_of_memory("the command", "running").what());
    } catch (const lancer::cli::CheckFailure& error) {
        return fail(1, "{}", error.what());
    } catch (const std::exception& error) {
        return fail(1, "internal error: {}", error.what());
    }
    return 0;
}
