// Flush-to-zero and denormals-are-zero for a scope: the floating-point mode Embree's manual asks its callers
// to set in every thread that traces ("Performance Recommendations", MXCSR). lancer's own structures keep
// IEEE denormals (docs/robustness.md), so the mode is scoped, and the caller's is restored at the end. The
// Embree structures set it around each call; a caller that traces many packets through Embree on one thread
// sets it once around them, as Embree's tutorials do, and the calls inside then leave the mode alone.
#pragma once

#if defined(__SSE__) || defined(__x86_64__)
#include <pmmintrin.h>  // _MM_DENORMALS_ZERO_ON
#include <xmmintrin.h>  // _mm_getcsr, _mm_setcsr
#endif

namespace lancer {

class DenormalsFlushed {
  public:
#if defined(__SSE__) || defined(__x86_64__)
    // The control register is written only when the mode is not set already: a write costs as much as tracing
    // a few rays (it waits for the floating-point operations in flight), a read does not.
    DenormalsFlushed() : caller_mode_(_mm_getcsr()) {
        if ((caller_mode_ & kFlushed) != kFlushed) _mm_setcsr(caller_mode_ | kFlushed);
    }
    ~DenormalsFlushed() {
        if ((caller_mode_ & kFlushed) != kFlushed) _mm_setcsr(caller_mode_);
    }
#else
    DenormalsFlushed() = default;  // no such mode to set
#endif
    DenormalsFlushed(const DenormalsFlushed&) = delete;
    DenormalsFlushed& operator=(const DenormalsFlushed&) = delete;

#if defined(__SSE__) || defined(__x86_64__)
  private:
    static constexpr unsigned int kFlushed = _MM_FLUSH_ZERO_ON | _MM_DENORMALS_ZERO_ON;
    unsigned int caller_mode_;
#endif
};

}  // namespace lancer
