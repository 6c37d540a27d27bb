#pragma once
// Internal: the recovery's sums over observations split over ranks (communicator.h). Each rank
// evaluates its share's loss and gradient; the shares are summed with allreduce_sum (rank order,
// so every rank gets the same bits) in one call.
#include <vector>

#include "wavebrdf/communicator.h"

namespace wavebrdf::detail {

// Sums `value` and `gradient` over the ranks (in place; one allreduce of gradient.size() + 1
// values) and returns the summed value. On one rank: `value`, the gradient untouched.
inline double allreduced(const Communicator& comm, std::vector<double>& gradient, double value) {
    if (comm.size() == 1) return value;
    gradient.push_back(value);
    comm.allreduce_sum(gradient);
    value = gradient.back();
    gradient.pop_back();
    return value;
}

}  // namespace wavebrdf::detail
