#include "frame_message.hpp"

#include <utility>

namespace lancer::cli {

std::vector<std::byte> serialise(const FramePart* part, const std::string& failure, int exit_code) {
    Writer writer;
    writer.put(static_cast<std::uint8_t>(part != nullptr ? 1 : 0));
    if (part == nullptr) {
        writer.put(static_cast<std::int32_t>(exit_code));
        writer.put_all(std::span<const char>(failure));
        return std::move(writer.bytes());
    }
    writer.put_all(std::span<const std::size_t>(part->tiles));
    writer.put_all(std::span<const Vec3f>(part->pixels));
    writer.put_all(std::span<const float>(part->depth));
    writer.put_all(std::span<const TraversalCounters>(part->heat));
    writer.put(part->stats.primary_rays), writer.put(part->stats.shadow_rays);
    writer.put(part->stats.reflection_rays), writer.put(part->stats.refraction_rays);
    return std::move(writer.bytes());
}

FramePart deserialise_part(Reader& reader) {
    FramePart part;
    part.tiles = reader.get_all<std::size_t>();
    part.pixels = reader.get_all<Vec3f>();
    part.depth = reader.get_all<float>();
    part.heat = reader.get_all<TraversalCounters>();
    part.stats.primary_rays = reader.get<std::uint64_t>();
    part.stats.shadow_rays = reader.get<std::uint64_t>();
    part.stats.reflection_rays = reader.get<std::uint64_t>();
    part.stats.refraction_rays = reader.get<std::uint64_t>();
    return part;
}

}  // namespace lancer::cli
