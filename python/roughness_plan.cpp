// What the recovery's planner reads from a known surface (roughness_plan.h): measure_roughness.

#include "common.h"
#include "recovery_args.h"
#include "wavebrdf/roughness_plan.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

void bind_roughness_plan(py::module_& m) {
    m.def(
        "measure_roughness",
        [](const Heightfield& heightfield) {
            MeasuredRoughness m;
            {
                py::gil_scoped_release release;
                m = measure_roughness(heightfield);
            }
            return roughness_dict(m);
        },
        "heightfield"_a, R"doc(
What the recovery's planner reads from a known surface (roughness_plan.h, measure_roughness):
a dict with range_um (peak to valley, um), rms_slope (rms |grad H|, central differences across
the periodic tile: the model's slopes), rim_fraction (fraction of texels with |grad H| > 0.5,
whose light leaves a slice under normal light), correlation_um (Sal, um), aspect (Str) and
lay_deg (Std, degrees from x towards y). plan_acquisition(roughness=...) and
recover(truth=...) plan for these.
)doc");
}

}  // namespace wavebrdf::python
