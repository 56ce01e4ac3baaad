#include "job_failure.hpp"

#include <new>
#include <stdexcept>

#include "common.hpp"
#include "distributed.hpp"
#include "lancer/load_scene.hpp"

namespace lancer::cli {

int exit_code_of(const std::exception_ptr& failure) {
    try {
        std::rethrow_exception(failure);
    } catch (const LoadError&) {
        return 2;
    } catch (const InputError&) {
        return 2;
    } catch (const std::bad_alloc&) {
        return 2;
    } catch (const JobError& error) {
        return error.exit_code();
    } catch (...) {
        return 1;
    }
}

std::string message_of(const std::exception_ptr& failure) {
    try {
        std::rethrow_exception(failure);
    } catch (const std::bad_alloc&) {
        return out_of_memory("the job's data", "running").what();
    } catch (const std::exception& error) {
        return error.what();
    } catch (...) {
        return "an unknown error";
    }
}

}  // namespace lancer::cli
