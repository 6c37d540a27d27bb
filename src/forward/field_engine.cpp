// The one place that makes field engines (field_engine.h).
#include "forward/field_engine.h"

#include <stdexcept>

#include "forward/fft_engine.h"
#include "forward/separable_engine.h"

namespace wavebrdf::detail {

template <typename Float>
std::unique_ptr<FieldEngine<Float>> make_field_engine(RenderPath path, const FootprintKernels& kernels,
                                                      const SliceGrid& grid, double lambda_um, int n, double tolerance,
                                                      bool keep_factors) {
    switch (path) {
        case RenderPath::Auto:
        case RenderPath::Separable: {
            auto engine = std::make_unique<SeparableEngine<Float>>(kernels, grid, lambda_um, n);
            engine->keep_factors(keep_factors);
            return engine;
        }
        case RenderPath::Fft: return std::make_unique<FftEngine<Float>>(kernels, grid, lambda_um, n, tolerance);
        case RenderPath::Direct: break;
    }
    throw std::invalid_argument("the direct path has no field engine; expected auto, separable or fft");
}

template std::unique_ptr<FieldEngine<float>> make_field_engine<float>(RenderPath, const FootprintKernels&,
                                                                      const SliceGrid&, double, int, double, bool);
template std::unique_ptr<FieldEngine<double>> make_field_engine<double>(RenderPath, const FootprintKernels&,
                                                                        const SliceGrid&, double, int, double, bool);

}  // namespace wavebrdf::detail
