// The slice plan (slice_plan.h): the height-independent part of a set of slice queries,
// computed once; set_heights / forward / adjoint reuse it.
#include "wavebrdf/slice_plan.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "core/denormals.h"
#include "forward/c3_nodes.h"
#include "forward/direct.h"
#include "forward/field_engine.h"
#include "forward/path_cost.h"
#include "forward/separable.h"
#include "forward/separable_engine.h"
#include "forward/kernel_gradient_detail.h"
#include "wavebrdf/kernel_gradient.h"
#include "wavebrdf/spectrum.h"

namespace wavebrdf {

namespace {
// Single-precision plans flush denormal operands while they render or differentiate
// (core/denormals.h); double plans keep gradual underflow, bit for bit as before.
struct NoFlush {};
template <typename Float>
using FlushIfFloat = std::conditional_t<std::is_same_v<Float, float>, detail::FlushDenormals, NoFlush>;
}  // namespace

void validate(const RenderOptions& options, Model model) {
    if (!(options.prune_tolerance >= 0.0 && options.prune_tolerance <= 1e-6))
        throw std::domain_error("prune tolerance " + std::to_string(options.prune_tolerance) +
                                " is out of range; expected 0 to 1e-6 of the slice peak");
    (void)model;  // every model has every path
    if (!(options.tolerance >= 1e-12 && options.tolerance <= 1e-2))
        throw std::domain_error("tolerance " + std::to_string(options.tolerance) +
                                " is out of range; expected 1e-12 to 1e-2 of the slice peak");
}

template <typename Float>
struct SlicePlan<Float>::State {
    // One wavelength: its height-independent tables and, after forward, its field and slice.
    struct Band {
        double lambda_um = 0.0;
        std::unique_ptr<detail::SliceGrid> grid;             // engine paths
        std::unique_ptr<detail::FieldEngine<Float>> engine;  // engine paths
        std::unique_ptr<detail::C3Nodes<Float>> nodes;       // engine paths, differentiable plans
        detail::ComplexMatrix<Float> field;                  // engine paths, kept for the adjoint
        detail::DirectField direct;                          // direct path, kept for the adjoint
        // The last forward took the direct sum (its tolerance needed too many C3 nodes).
        bool direct_used = false;
        std::vector<Float> slice;
    };

    int rows = 0, cols = 0;
    double texel_um = 0.0, vscale = 0.0;
    Query query;
    int n = 0;
    int channels = 3;
    RenderOptions options;
    bool separable = false;
    bool differentiable = true;
    FootprintKernels kernels;  // geometry fixed; height_um and slopes follow set_heights
    std::vector<double> lambdas_um;
    std::vector<double> mix;  // 3 × N (channels 3)
    std::vector<Band> bands;
    std::vector<Float> output;
    bool forward_done = false;

    // The engine for wavelength λ: the path asked for, or Auto resolved by the cost model from
    // the footprint's current kernels (the steepest slope sets the FFT grid).
    RenderPath engine_path(double lambda_um) const {
        if (options.path != RenderPath::Auto) return options.path;
        detail::FieldPathInputs in;
        in.n = n;
        in.lambda_um = lambda_um;
        in.kernels = kernels.size();
        in.texel_um = texel_um;
        for (std::size_t k = 0; k < kernels.size(); ++k)
            in.max_slope = std::max({in.max_slope, std::abs(kernels.slope_x[k]), std::abs(kernels.slope_y[k])});
        in.tolerance = options.tolerance;
        in.omega_ix = query.omega_i[0];
        in.omega_iy = query.omega_i[1];
        in.views = query.model == Model::Kirchhoff ? 3 : 1;
        return detail::choose_field_path(in);
    }

    // Per-kernel gradient of Σ weights · slice(l) (weights: n²), after forward.
    KernelGradient band_gradient(std::size_t wavelength, const std::vector<Float>& weights) const;
    // position += ∂L/∂(x_um, y_um) from a band's per-kernel gradient.
    void add_position(const KernelGradient& g, std::array<double, 2>& position) const;
    // Every band's gradient for output weights (scaled): into *gradient (heights) when given,
    // and the footprint centre's, returned.
    std::array<double, 2> all_bands(const std::vector<double>& weights, double scale,
                                    std::vector<double>* gradient) const;

    // One wavelength's slice for the current heights (forward's body; bands are independent).
    std::vector<Float> band_forward(Band& b);

    std::size_t cells() const { return static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols); }
    double value(const std::vector<double>& h, int i, int j) const {
        i %= rows;
        if (i < 0) i += rows;
        j %= cols;
        if (j < 0) j += cols;
        return h[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)];
    }

    void require_forward(const char* what) const {
        if (!differentiable)
            throw std::logic_error(std::string(what) + " needs a differentiable plan; this one is forward-only");
        if (!forward_done) throw std::logic_error(std::string(what) + " needs forward() first");
    }
};

template <typename Float>
SlicePlan<Float>::SlicePlan(const Heightfield& hf, const Query& query, const std::vector<double>& lambdas_um,
                            int resolution, int channels, const RenderOptions& options, bool differentiable)
    : m_state(std::make_unique<State>()) {
    validate(query);
    validate_resolution(resolution);
    validate(options, query.model);
    if (lambdas_um.empty()) throw std::invalid_argument("no wavelengths given; expected at least one");
    for (double lambda : lambdas_um) validate_lambda(lambda);
    if (channels != 1 && channels != 3)
        throw std::invalid_argument("channels " + std::to_string(channels) + " is invalid; expected 1 or 3");
    if (channels == 1 && lambdas_um.size() != 1)
        throw std::invalid_argument("one output channel needs one wavelength; " + std::to_string(lambdas_um.size()) +
                                    " given");
    State& s = *m_state;
    s.rows = hf.rows();
    s.cols = hf.cols();
    s.texel_um = hf.texel_um();
    s.vscale = hf.vscale();
    s.query = query;
    s.n = resolution;
    s.channels = channels;
    s.options = options;
    // Auto: the separable or the FFT engine for every model, whichever the cost model
    // (path_cost.h) says is cheaper for this slice size, wavelength and footprint.
    s.separable = options.path != RenderPath::Direct;
    s.differentiable = differentiable;
    s.kernels = footprint_kernels(hf, query.x_um, query.y_um, query.sigma_p_um);
    s.lambdas_um = lambdas_um;
    if (channels == 3) s.mix = spectral_mix_weights(lambdas_um);
    s.bands.resize(lambdas_um.size());
    for (std::size_t l = 0; l < lambdas_um.size(); ++l) {
        typename State::Band& b = s.bands[l];
        b.lambda_um = lambdas_um[l];
        if (!s.separable) continue;
        b.grid = std::make_unique<detail::SliceGrid>(query, b.lambda_um, resolution);
        b.engine = detail::make_field_engine<Float>(s.engine_path(b.lambda_um), s.kernels, *b.grid, b.lambda_um,
                                                    resolution, options.tolerance, differentiable);
        if (differentiable)
            b.nodes = std::make_unique<detail::C3Nodes<Float>>(query, *b.grid, b.lambda_um, resolution,
                                                               options.tolerance);
    }
}

template <typename Float>
SlicePlan<Float>::~SlicePlan() = default;
template <typename Float>
SlicePlan<Float>::SlicePlan(SlicePlan&&) noexcept = default;
template <typename Float>
SlicePlan<Float>& SlicePlan<Float>::operator=(SlicePlan&&) noexcept = default;

template <typename Float>
void SlicePlan<Float>::set_heights(const std::vector<double>& values) {
    State& s = *m_state;
    if (values.size() != s.cells())
        throw std::invalid_argument("heights have " + std::to_string(values.size()) +
                                    " values; expected rows*cols = " + std::to_string(s.cells()));
    // Only the values the footprint reads (its kernels' texels and their neighbours) are
    // checked: the others cannot change the slice, and checking all rows·cols per plan made a
    // recovery's iteration quadratic in the area (one plan per observation).
    FootprintKernels& k = s.kernels;
    const auto check = [&](int i, int j) {
        i %= s.rows;
        if (i < 0) i += s.rows;
        j %= s.cols;
        if (j < 0) j += s.cols;
        const std::size_t at = static_cast<std::size_t>(i) * static_cast<std::size_t>(s.cols) +
                               static_cast<std::size_t>(j);
        if (!std::isfinite(values[at]))
            throw std::domain_error("height value " + std::to_string(at) + " is not finite; expected finite heights");
    };
    for (std::size_t idx = 0; idx < k.size(); ++idx) {
        const int i = k.row[idx], j = k.col[idx];
        check(i, j);
        check(i + 1, j);
        check(i - 1, j);
        check(i, j + 1);
        check(i, j - 1);
    }
    // As Heightfield::height_um and Heightfield::slope, term for term (so bit for bit).
    for (std::size_t idx = 0; idx < k.size(); ++idx) {
        const int i = k.row[idx], j = k.col[idx];
        k.height_um[idx] = s.vscale * s.texel_um * s.value(values, i, j);
        k.slope_x[idx] = 0.5 * s.vscale * (s.value(values, i + 1, j) - s.value(values, i - 1, j));
        k.slope_y[idx] = 0.5 * s.vscale * (s.value(values, i, j + 1) - s.value(values, i, j - 1));
    }
    s.forward_done = false;
}

template <typename Float>
void SlicePlan<Float>::set_heights(const Heightfield& hf) {
    const State& s = *m_state;
    if (hf.rows() != s.rows || hf.cols() != s.cols || hf.texel_um() != s.texel_um || hf.vscale() != s.vscale)
        throw std::invalid_argument("heightfield " + std::to_string(hf.rows()) + "x" + std::to_string(hf.cols()) +
                                    " does not have the plan's geometry (" + std::to_string(s.rows) + "x" +
                                    std::to_string(s.cols) + ", same texel width and vertical scale)");
    set_heights(hf.values());
}

template <typename Float>
const std::vector<Float>& SlicePlan<Float>::forward() {
    State& s = *m_state;
    const std::size_t pixels = static_cast<std::size_t>(s.n) * static_cast<std::size_t>(s.n);
    s.forward_done = false;
    s.output.assign(pixels * static_cast<std::size_t>(s.channels), Float(0));
    // Several wavelengths: one band per thread (each band's engine then runs serially inside
    // the region, core/parallel.h), which keeps both cores busy on small slices where a single
    // band's engine is too small to split; the mix below stays in band order.
    std::vector<std::vector<Float>> slices(s.bands.size());
    detail::RegionGuard guard;
#pragma omp parallel for schedule(dynamic, 1) if (s.bands.size() > 1 && !detail::in_parallel_region())
    for (std::size_t l = 0; l < s.bands.size(); ++l) guard.run([&] { slices[l] = s.band_forward(s.bands[l]); });
    guard.rethrow();
    for (std::size_t l = 0; l < s.bands.size(); ++l) {
        typename State::Band& b = s.bands[l];
        std::vector<Float>& slice = slices[l];
        if (s.channels == 1)
            s.output = slice;
        else
            mix_spectral_to_rgb<Float>(s.mix, l, slice, s.output);
        if (s.differentiable) b.slice = std::move(slice);
    }
    s.forward_done = true;
    return s.output;
}

template <typename Float>
std::vector<Float> SlicePlan<Float>::State::band_forward(Band& b) {
    State& s = *this;
    [[maybe_unused]] const FlushIfFloat<Float> flush{};  // float: denormal operands cost ~30× (core/denormals.h)
    {
        std::vector<Float> slice;
        if (s.separable) {
            // Forward-only plans make the per-pixel tables for each call (as many as the
            // direct path computes anyway) instead of keeping one pair per wavelength.
            std::unique_ptr<detail::C3Nodes<Float>> own;
            if (!b.nodes)
                own = std::make_unique<detail::C3Nodes<Float>>(s.query, *b.grid, b.lambda_um, s.n, s.options.tolerance);
            detail::C3Nodes<Float>& nodes = b.nodes ? *b.nodes : *own;
            detail::ComplexMatrix<Float> field;
            slice = nodes.forward(*b.engine, s.kernels, field, s.options.progress);
            b.direct_used = slice.empty();
            if (s.differentiable && !b.direct_used) b.field = std::move(field);
            if (b.direct_used)
                b.field = detail::ComplexMatrix<Float>();
            else
                b.direct = detail::DirectField();
        }
        // The direct path, or the separable one when its tolerance needs more C3 nodes than
        // the direct sum costs (c3_nodes.h).
        if (!s.separable || b.direct_used) {
            detail::DirectField direct = detail::direct_field(s.kernels, s.query, b.lambda_um, s.n,
                                                              s.options.prune_tolerance, s.options.progress);
            slice.assign(direct.value.begin(), direct.value.end());
            if (s.differentiable) b.direct = std::move(direct);
        }
        return slice;
    }
}

template <typename Float>
const std::vector<Float>& SlicePlan<Float>::slice(std::size_t wavelength) const {
    const State& s = *m_state;
    s.require_forward("SlicePlan::slice");
    if (wavelength >= s.bands.size())
        throw std::invalid_argument("wavelength index " + std::to_string(wavelength) +
                                    " is out of range; expected below " + std::to_string(s.bands.size()));
    return s.bands[wavelength].slice;
}

template <typename Float>
KernelGradient SlicePlan<Float>::State::band_gradient(std::size_t wavelength, const std::vector<Float>& weights) const {
    const State& s = *this;
    [[maybe_unused]] const FlushIfFloat<Float> flush{};
    s.require_forward("SlicePlan::adjoint");
    if (wavelength >= s.bands.size())
        throw std::invalid_argument("wavelength index " + std::to_string(wavelength) +
                                    " is out of range; expected below " + std::to_string(s.bands.size()));
    const std::size_t pixels = static_cast<std::size_t>(s.n) * static_cast<std::size_t>(s.n);
    if (weights.size() != pixels)
        throw std::invalid_argument("weights have " + std::to_string(weights.size()) +
                                    " entries; expected resolution^2 = " + std::to_string(pixels));
    const Band& b = s.bands[wavelength];
    return s.separable && !b.direct_used ? b.nodes->adjoint(*b.engine, s.kernels, b.field, weights)
                                         : detail::direct_backward(s.kernels, s.query, b.lambda_um, s.n, b.direct,
                                                                   std::vector<double>(weights.begin(), weights.end()));
}

template <typename Float>
void SlicePlan<Float>::State::add_position(const KernelGradient& g, std::array<double, 2>& position) const {
    // c_k ∝ exp(−|δ_k|²/(2σ_p²)), δ_k = μ_k − μ_p: ∂ln c_k/∂μ_p = δ_k/σ_p².
    const double inv_var = 1.0 / (query.sigma_p_um * query.sigma_p_um);
    double gx = 0.0, gy = 0.0;
    for (std::size_t k = 0; k < kernels.size(); ++k) {
        gx += g.log_weight[k] * kernels.dx_um[k];
        gy += g.log_weight[k] * kernels.dy_um[k];
    }
    position[0] += gx * inv_var;
    position[1] += gy * inv_var;
}

template <typename Float>
void SlicePlan<Float>::adjoint_wavelength(std::size_t wavelength, const std::vector<Float>& weights,
                                          std::vector<double>& gradient) const {
    const State& s = *m_state;
    s.require_forward("SlicePlan::adjoint");
    detail::prepare_gradient(gradient, s.cells());
    const KernelGradient g = s.band_gradient(wavelength, weights);
    detail::scatter_to_heights(s.rows, s.cols, s.texel_um, s.vscale, s.kernels, g, gradient);
}

template <typename Float>
std::array<double, 2> SlicePlan<Float>::State::all_bands(const std::vector<double>& weights, double scale,
                                                         std::vector<double>* gradient) const {
    const State& s = *this;
    s.require_forward("SlicePlan::adjoint");
    const std::size_t pixels = static_cast<std::size_t>(s.n) * static_cast<std::size_t>(s.n);
    if (weights.size() != pixels * static_cast<std::size_t>(s.channels))
        throw std::invalid_argument("weights have " + std::to_string(weights.size()) +
                                    " entries; expected resolution^2 * channels = " +
                                    std::to_string(pixels * static_cast<std::size_t>(s.channels)));
    if (gradient) detail::prepare_gradient(*gradient, s.cells());
    std::array<double, 2> position{0.0, 0.0};
    std::vector<Float> w(pixels);
    for (std::size_t l = 0; l < s.bands.size(); ++l) {
        if (s.channels == 1)
            for (std::size_t p = 0; p < pixels; ++p) w[p] = Float(scale * weights[p]);
        else
            mix_spectral_to_rgb_adjoint<Float>(s.mix, l, weights, w, scale);
        const KernelGradient g = s.band_gradient(l, w);
        if (gradient) detail::scatter_to_heights(s.rows, s.cols, s.texel_um, s.vscale, s.kernels, g, *gradient);
        s.add_position(g, position);
    }
    return position;
}

template <typename Float>
void SlicePlan<Float>::adjoint(const std::vector<double>& weights, std::vector<double>& gradient, double scale) const {
    m_state->all_bands(weights, scale, &gradient);
}

template <typename Float>
std::array<double, 2> SlicePlan<Float>::position_gradient(const std::vector<double>& weights) const {
    return m_state->all_bands(weights, 1.0, nullptr);
}

template <typename Float>
std::array<double, 2> SlicePlan<Float>::adjoint_with_position(const std::vector<double>& weights,
                                                              std::vector<double>& gradient, double scale) const {
    return m_state->all_bands(weights, scale, &gradient);
}

template <typename Float>
void SlicePlan<Float>::release() {
    State& s = *m_state;
    for (typename State::Band& b : s.bands) {
        b.field = detail::ComplexMatrix<Float>();
        if (auto* engine = dynamic_cast<detail::SeparableEngine<Float>*>(b.engine.get()))
            engine->release_tables();  // kept factors and phase tables (rebuilt by the next call)
        b.direct = detail::DirectField();
        b.slice = std::vector<Float>();
    }
    s.output = std::vector<Float>();
    s.forward_done = false;
}

template <typename Float>
bool SlicePlan<Float>::matches(const Heightfield& hf, const Query& query, const std::vector<double>& lambdas_um,
                               int resolution, int channels, const RenderOptions& options) const {
    const State& s = *m_state;
    return hf.rows() == s.rows && hf.cols() == s.cols && hf.texel_um() == s.texel_um && hf.vscale() == s.vscale &&
           query.x_um == s.query.x_um && query.y_um == s.query.y_um && query.sigma_p_um == s.query.sigma_p_um &&
           query.omega_i == s.query.omega_i && query.model == s.query.model && lambdas_um == s.lambdas_um &&
           resolution == s.n && channels == s.channels && options.path == s.options.path &&
           options.prune_tolerance == s.options.prune_tolerance && options.tolerance == s.options.tolerance &&
           options.progress == s.options.progress;
}

template <typename Float>
void SlicePlan<Float>::gradient_box(std::vector<int>& rows, std::vector<int>& cols) const {
    const State& s = *m_state;
    std::vector<char> row_used(static_cast<std::size_t>(s.rows), 0), col_used(static_cast<std::size_t>(s.cols), 0);
    for (std::size_t k = 0; k < s.kernels.size(); ++k)
        for (int d = -1; d <= 1; ++d) {  // as scatter_to_heights: (i, j), (i ± 1, j), (i, j ± 1)
            row_used[static_cast<std::size_t>(((s.kernels.row[k] + d) % s.rows + s.rows) % s.rows)] = 1;
            col_used[static_cast<std::size_t>(((s.kernels.col[k] + d) % s.cols + s.cols) % s.cols)] = 1;
        }
    rows.clear();
    cols.clear();
    for (int i = 0; i < s.rows; ++i)
        if (row_used[static_cast<std::size_t>(i)]) rows.push_back(i);
    for (int j = 0; j < s.cols; ++j)
        if (col_used[static_cast<std::size_t>(j)]) cols.push_back(j);
}

template <typename Float>
int SlicePlan<Float>::resolution() const {
    return m_state->n;
}
template <typename Float>
int SlicePlan<Float>::channels() const {
    return m_state->channels;
}
template <typename Float>
std::size_t SlicePlan<Float>::wavelengths() const {
    return m_state->bands.size();
}
template <typename Float>
std::size_t SlicePlan<Float>::kernels() const {
    return m_state->kernels.size();
}

template class SlicePlan<float>;
template class SlicePlan<double>;

}  // namespace wavebrdf
