// The grayscale relief's filtered parameterisation (feature_filter.h).
#include "design/feature_filter.h"

#include <fftw3.h>

#include <cmath>
#include <complex>
#include <mutex>
#include <stdexcept>

#include "core/fftw_raii.h"
#include "wavebrdf/text.h"

namespace wavebrdf::detail {

struct FeatureFilter::Plans {
    FftwBuffer<fftw_complex> buffer;
    FftwPlan forward, backward;  // destroyed before the buffer (declared after it)
    mutable std::mutex mutex;    // apply() shares the buffer
};

FeatureFilter::FeatureFilter(int size, double texel_um, double min_feature_um) : m_size(size) {
    if (!(size >= 2 && size <= 2048))
        throw std::domain_error("tile size " + std::to_string(size) + " is out of range; expected 2 to 2048");
    if (!(texel_um > 0.0 && std::isfinite(texel_um)))
        throw std::domain_error("--texel-um " + format_shortest(texel_um) + " is not a width; expected > 0");
    if (!(min_feature_um >= 2.0 * texel_um && std::isfinite(min_feature_um)))
        throw std::domain_error("--min-feature-um " + format_shortest(min_feature_um) +
                                " is below two texels; expected at least 2 x --texel-um = " +
                                format_shortest(2.0 * texel_um) + " um");
    const std::size_t N = static_cast<std::size_t>(size), n2 = N * N;
    m_plans = std::make_unique<Plans>();
    {
        std::lock_guard<std::mutex> lock(fftw_planner_mutex());
        m_plans->buffer = fftw_buffer<fftw_complex>(n2);
        fftw_complex* b = m_plans->buffer.get();
        m_plans->forward.reset(fftw_plan_dft_2d(size, size, b, b, FFTW_FORWARD, FFTW_ESTIMATE));
        m_plans->backward.reset(fftw_plan_dft_2d(size, size, b, b, FFTW_BACKWARD, FFTW_ESTIMATE));
    }
    // The disc |ν| ≤ 1/(2F) on the DFT grid (signed indices), its inverse DFT d, the kernel |d|²
    // normalised to sum 1, and the kernel's DFT: the transfer (real: the kernel is even).
    const double L = size * texel_um, radius = L / (2.0 * min_feature_um);  // in DFT index units
    auto* b = reinterpret_cast<std::complex<double>*>(m_plans->buffer.get());
    for (std::size_t i = 0; i < N; ++i)
        for (std::size_t j = 0; j < N; ++j) {
            const double m = i <= N / 2 ? static_cast<double>(i) : static_cast<double>(i) - size;
            const double n = j <= N / 2 ? static_cast<double>(j) : static_cast<double>(j) - size;
            b[i * N + j] = std::hypot(m, n) <= radius ? 1.0 : 0.0;
        }
    fftw_execute(m_plans->backward.get());
    double sum = 0.0;
    for (std::size_t t = 0; t < n2; ++t) sum += std::norm(b[t]);
    for (std::size_t t = 0; t < n2; ++t) b[t] = std::norm(b[t]) / sum;
    fftw_execute(m_plans->forward.get());
    m_transfer.resize(n2);
    for (std::size_t t = 0; t < n2; ++t) m_transfer[t] = b[t].real();
}

FeatureFilter::~FeatureFilter() = default;

void FeatureFilter::apply(const std::vector<double>& in, std::vector<double>& out) const {
    const std::size_t n2 = static_cast<std::size_t>(m_size) * static_cast<std::size_t>(m_size);
    if (in.size() != n2) throw std::invalid_argument("FeatureFilter::apply: wrong size");
    std::lock_guard<std::mutex> lock(m_plans->mutex);
    auto* b = reinterpret_cast<std::complex<double>*>(m_plans->buffer.get());
    for (std::size_t t = 0; t < n2; ++t) b[t] = in[t];
    fftw_execute(m_plans->forward.get());
    for (std::size_t t = 0; t < n2; ++t) b[t] *= m_transfer[t] / static_cast<double>(n2);
    fftw_execute(m_plans->backward.get());
    out.resize(n2);
    for (std::size_t t = 0; t < n2; ++t) out[t] = b[t].real();
}

void filtered_heights(const FeatureFilter& filter, double height_range_um, const std::vector<double>& z,
                      std::vector<double>& heights_um) {
    std::vector<double> u(z.size());
    for (std::size_t t = 0; t < z.size(); ++t) u[t] = 1.0 / (1.0 + std::exp(-z[t]));
    filter.apply(u, heights_um);
    for (double& h : heights_um) h *= height_range_um;
}

void filtered_heights_adjoint(const FeatureFilter& filter, double height_range_um, const std::vector<double>& z,
                              const std::vector<double>& heights_gradient, std::vector<double>& z_gradient) {
    filter.apply(heights_gradient, z_gradient);
    for (std::size_t t = 0; t < z.size(); ++t) {
        const double s = 1.0 / (1.0 + std::exp(-z[t]));
        z_gradient[t] *= height_range_um * s * (1.0 - s);
    }
}

}  // namespace wavebrdf::detail
