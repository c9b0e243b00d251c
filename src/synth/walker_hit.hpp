#pragma once
/// \file walker_hit.hpp (private)
/// Ray and walker: the intersection of Walker::hit with the axis already placed, for the
/// renderer (which places every walker once per row and sub-exposure, not once per ray).

#include <Eigen/Core>
#include <optional>

#include "omnipose/synth/scene.hpp"

namespace omnipose::synth::detail {

/// Walker::hit for the walker's axis at `axis` (x, y), metres.
std::optional<double> hitWalker(const Walker& walker, const Eigen::Vector2d& axis,
                                const Eigen::Vector3d& origin, const Eigen::Vector3d& direction);

}  // namespace omnipose::synth::detail
