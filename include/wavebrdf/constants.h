#pragma once
// Mathematical constants shared by the library, its front ends and its tests: one name each.

namespace wavebrdf {

// π, the double nearest to it (2 * k_pi is the double nearest to 2π).
inline constexpr double k_pi = 3.14159265358979323846;

}  // namespace wavebrdf
