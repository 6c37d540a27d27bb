#pragma once
// Internal: how a recovery stage reports a step (recover.h, StageMetrics).
#include <functional>
#include <string>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/recover.h"

namespace wavebrdf::detail {

// A reported step's stage: its kind (recover.h, StageKind), given where the step is reported so
// that no one reads it back from the text, and its metrics text: the kind's name for a kind
// named whole ("unwrap"), or for a kind named per width, wavelength or model (a name ending in
// ':') that prefix and the part after it ("field:" and "0.7").
struct StageId {
    StageId(StageKind k) : kind(k), name(stage_kind_name(k)) {}  // NOLINT: implicit by design
    StageId(StageKind k, const std::string& part) : kind(k), name(stage_kind_name(k) + part) {}
    StageKind kind;
    std::string name;
};

// The part after a per-width or per-wavelength kind's prefix: the number as "%g" writes it.
std::string stage_part(double value);

// report(stage, iteration, loss, heights): one StageMetrics of recover_heights (heights null
// where the stage has none yet); false: stop.
using StageReport = std::function<bool(const StageId&, int, double, const Heightfield*)>;

}  // namespace wavebrdf::detail
