// The namespace of code whose machine code depends on the instruction set it is compiled for. A source
// compiled twice (the AVX2 baseline in lancer_core, AVX-512 in lancer_kernels_avx512, which defines
// LANCER_KERNEL_AVX512) puts its SIMD types and kernels here, so that the two compilations' inline
// functions carry different names: otherwise the linker keeps one copy of each, and an AVX-512 copy could
// run where only AVX2 is (docs/isa.md; tests/core/isa_symbols_test.sh checks the objects).
#pragma once

#if defined(LANCER_KERNEL_AVX512)
#define LANCER_ISA_NAMESPACE avx512
#elif defined(__CUDACC__)
// nvcc's host pass compiles the shared scalar kernels without the library's -march: their own names.
#define LANCER_ISA_NAMESPACE cuda
#else
#define LANCER_ISA_NAMESPACE avx2
#endif
