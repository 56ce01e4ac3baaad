// What the BVH traversals of src/cuda/ add to core/host_device.hpp's helpers: record loads through the
// read-only cache.
#pragma once

#include <cstdint>
#include <cstring>

#include "core/host_device.hpp"
#include "lancer/ray.hpp"
#include "lancer/vec.hpp"

namespace lancer::gpu {

// A record of whole 8-byte words (a 40-byte triangle, a 64-byte node) through the read-only cache, as
// float2 loads: the arrays come from cudaMalloc (256-byte aligned) and every record size is a multiple of 8.
template <class Record>
LANCER_HOST_DEVICE inline Record read_only_record(const Record* address) {
    static_assert(sizeof(Record) % 8 == 0);
#if defined(__CUDA_ARCH__)
    Record record;
    const float2* words = reinterpret_cast<const float2*>(address);
    float2 loaded[sizeof(Record) / 8];
#pragma unroll
    for (unsigned i = 0; i < sizeof(Record) / 8; ++i)
        loaded[i] = __ldg(words + i);
    memcpy(&record, loaded, sizeof(Record));
    return record;
#else
    Record record;
    std::memcpy(&record, address, sizeof(Record));
    return record;
#endif
}

}  // namespace lancer::gpu
