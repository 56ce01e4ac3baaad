// LANCER_HOST_DEVICE marks a function that one source gives to both the CPU (g++) and the GPU (nvcc): the
// kernels CPU and GPU share are written once (docs/cuda.md).
#pragma once

#if defined(__CUDACC__)
#define LANCER_HOST_DEVICE __host__ __device__
#else
#define LANCER_HOST_DEVICE
#endif
