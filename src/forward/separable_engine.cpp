// The separable engine (separable_engine.h). Forward: per chunk of kernels, X and Y once, then
// for each weight vector F_v += X · (Y·diag(w_v))ᵀ. Adjoint (field_engine.h's convention), with
// Z_v = B_v·Y and V_v = B_vᵀ·X (two products of the forward's size per vector):
//   weight[v][k] = Σ_p X[p,k] Z_v[p,k]
//   shift_x[k]   = 2 Re Σ_v w_vk Σ_p ∂_b X[p,k] Z_v[p,k],  ∂_b X = −4π²σ²(u_x + b_x) X
//   shift_y[k]   = 2 Re Σ_v w_vk Σ_q ∂_b Y[q,k] V_v[q,k].
#include "forward/separable_engine.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "wavebrdf/memory.h"

namespace wavebrdf::detail {

namespace {

// When the adjoint rebuilds factors it holds four n × chunk matrices (X, Y, Z, V): 512 kernels
// keep its peak below the forward's at no measurable cost in the products.
constexpr Eigen::Index kAdjointChunkColumns = 512;
// Factors kept for the adjoint beyond the first shift_scale's.
constexpr double kKeptBytes = 64.0 * (1 << 20);

void check_weights(const KernelWeights& weights, std::size_t kernels) {
    for (std::size_t v = 0; v < weights.size(); ++v)
        if (weights[v].size() != kernels)
            throw std::invalid_argument("weight vector " + std::to_string(v) + " has " +
                                        std::to_string(weights[v].size()) + " entries; expected one per kernel (" +
                                        std::to_string(kernels) + ")");
}

template <typename Float>
void check_cotangents(const std::vector<ComplexMatrix<Float>>& cotangents, std::size_t vectors, int n) {
    if (cotangents.size() != vectors)
        throw std::invalid_argument("cotangents are " + std::to_string(cotangents.size()) +
                                    " matrices; expected one per weight vector (" + std::to_string(vectors) + ")");
    for (const ComplexMatrix<Float>& b : cotangents)
        if (b.rows() != n || b.cols() != n)
            throw std::invalid_argument("a cotangent is " + std::to_string(b.rows()) + "x" + std::to_string(b.cols()) +
                                        "; expected the slice's " + std::to_string(n) + "x" + std::to_string(n));
}

}  // namespace

void build_planar_factors(const FootprintKernels& k, const SliceGrid& grid, const PhaseTables& phases, double lambda_um,
                          double shift_scale, Eigen::Index k0, Eigen::Index count, PlanarFactors& xs,
                          PlanarFactors& ys) {
    const Eigen::Index n = static_cast<Eigen::Index>(grid.ux.size());
    // As build_factors: Complex(g · phase) rounds each part of the double product.
    const auto write = [n](const double* g, const std::complex<double>* phase, float* re, float* im, float* sum) {
        const double* ph = reinterpret_cast<const double*>(phase);
        for (Eigen::Index p = 0; p < n; ++p) {
            re[p] = float(g[p] * ph[2 * p]);
            im[p] = float(g[p] * ph[2 * p + 1]);
            sum[p] = re[p] + im[p];
        }
    };
    for_each_factor_column(k, grid, phases, lambda_um, shift_scale, k0, count,
                           [&](Eigen::Index c, const double* gx, const double* gy, const std::complex<double>* px,
                               const std::complex<double>* py) {
                               write(gx, px, &xs.re(0, c), &xs.im(0, c), &xs.sum(0, c));
                               write(gy, py, &ys.re(0, c), &ys.im(0, c), &ys.sum(0, c));
                           });
}

template <typename Float>
SeparableEngine<Float>::SeparableEngine(const FootprintKernels& kernels, const SliceGrid& grid, double lambda_um, int n)
    : m_kernels(kernels), m_grid(grid), m_lambda_um(lambda_um), m_n(n) {}

template <typename Float>
const PhaseTables& SeparableEngine<Float>::phases() {
    if (!m_phases) m_phases = std::make_unique<PhaseTables>(m_kernels, m_grid);
    return *m_phases;
}

template <typename Float>
void SeparableEngine<Float>::release_tables() {
    m_phases.reset();
    m_kept.clear();
    m_kept_bytes = 0.0;
    m_kept_slope_x = std::vector<double>();
    m_kept_slope_y = std::vector<double>();
}

template <typename Float>
void SeparableEngine<Float>::keep_factors(bool keep) {
    m_keep = keep;
    if (!keep) {
        m_kept.clear();
        m_kept_bytes = 0.0;
    }
}

template <typename Float>
const typename SeparableEngine<Float>::Kept* SeparableEngine<Float>::kept(double shift_scale) {
    if (m_kept.empty()) return nullptr;
    if (m_kept_slope_x != m_kernels.slope_x || m_kept_slope_y != m_kernels.slope_y) {
        m_kept.clear();
        m_kept_bytes = 0.0;
        return nullptr;
    }
    for (const Kept& k : m_kept)
        if (k.shift_scale == shift_scale) return &k;
    return nullptr;
}

template <typename Float>
bool SeparableEngine<Float>::admit(double bytes) {
    if (!m_kept.empty() && m_kept_bytes + bytes > kKeptBytes) return false;
    if (m_kept.empty()) {
        m_kept_slope_x = m_kernels.slope_x;
        m_kept_slope_y = m_kernels.slope_y;
    }
    m_kept_bytes += bytes;
    return true;
}

template <typename Float>
void SeparableEngine<Float>::keep(double shift_scale, ComplexMatrix<Float>& xs, ComplexMatrix<Float>& ys) {
    if (!admit(2.0 * double(xs.size()) * sizeof(std::complex<Float>))) return;
    Kept k;
    k.shift_scale = shift_scale;
    k.xs = std::move(xs);
    k.ys = std::move(ys);
    m_kept.push_back(std::move(k));
}

template <typename Float>
void SeparableEngine<Float>::keep(double shift_scale, PlanarFactors& px, PlanarFactors& py) {
    if (!admit(6.0 * double(px.re.size()) * sizeof(float))) return;
    Kept k;
    k.shift_scale = shift_scale;
    k.px = std::move(px);
    k.py = std::move(py);
    m_kept.push_back(std::move(k));
}

template <typename Float>
void SeparableEngine<Float>::PlanarChunk::reserve(Eigen::Index rows, Eigen::Index cols) {
    if (cached) return;
    planar_x.resize(rows, cols);
    planar_y.resize(rows, cols);
}

template <typename Float>
Eigen::Index SeparableEngine<Float>::load_chunk(double shift_scale, Eigen::Index k0, Eigen::Index count,
                                                PlanarChunk& chunk) {
    if (chunk.cached) return k0;
    build_planar_factors(m_kernels, m_grid, phases(), m_lambda_um, shift_scale, k0, count, chunk.planar_x,
                         chunk.planar_y);
    return 0;
}

template <typename Float>
void SeparableEngine<Float>::forward(const KernelWeights& weights, double shift_scale,
                                     std::vector<ComplexMatrix<Float>>& fields) {
    if constexpr (std::is_same_v<Float, float>) {
        forward_planar(weights, shift_scale, fields);
        return;
    }
    using Complex = std::complex<Float>;
    const int n = m_n;
    const Eigen::Index total = static_cast<Eigen::Index>(m_kernels.size());
    check_weights(weights, m_kernels.size());
    const std::string size = std::to_string(n) + "x" + std::to_string(n);
    fields.resize(weights.size());
    allocating("the " + size + " slice's " + std::to_string(weights.size()) + " field(s)",
               double(weights.size()) * double(n) * n * sizeof(Complex), [&] {
                   for (ComplexMatrix<Float>& f : fields) f.setZero(n, n);
               });
    const Kept* cached = kept(shift_scale);
    const Eigen::Index chunk = cached ? std::max<Eigen::Index>(total, 1) : chunk_size(n, sizeof(Complex), 3);
    const Eigen::Index cols = std::min(chunk, std::max<Eigen::Index>(total, 1));
    ComplexMatrix<Float> built_xs, built_ys, yw;
    allocating("the " + size + " slice's factor matrices",
               (cached ? 1.0 : 3.0) * double(n) * double(cols) * sizeof(Complex), [&] {
                   if (!cached) {
                       built_xs.resize(n, cols);
                       built_ys.resize(n, cols);
                   }
                   yw.resize(n, cols);
               });
    const ComplexMatrix<Float>& xs = cached ? cached->xs : built_xs;
    const ComplexMatrix<Float>& ys = cached ? cached->ys : built_ys;
    for (Eigen::Index k0 = 0; k0 < total; k0 += chunk) {
        const Eigen::Index count = std::min(chunk, total - k0);
        const Eigen::Index base = cached ? k0 : 0;
        if (!cached)
            build_factors<Float>(m_kernels, m_grid, phases(), m_lambda_um, shift_scale, k0, count, built_xs, built_ys);
        for (std::size_t v = 0; v < weights.size(); ++v) {
            // Y·diag(w_v): the weights enter the smaller factor.
            for (Eigen::Index c = 0; c < count; ++c) {
                const std::complex<double> w = weights[v][static_cast<std::size_t>(k0 + c)];
                yw.col(c) = ys.col(base + c) * Complex(Float(w.real()), Float(w.imag()));
            }
            ComplexMatrix<Float>& field = fields[v];
            for_column_blocks(n, double(n) * n * double(count), [&](long long first, long long block) {
                field.middleCols(first, block).noalias() += xs.middleCols(base, count) *
                                                            yw.leftCols(count).middleRows(first, block).transpose();
            });
        }
    }
    if (m_keep && !cached && total > 0 && total <= chunk) keep(shift_scale, built_xs, built_ys);
}

template <typename Float>
void SeparableEngine<Float>::adjoint(const KernelWeights& weights, double shift_scale,
                                     const std::vector<ComplexMatrix<Float>>& cotangents, FieldGradient& gradient) {
    using Complex = std::complex<Float>;
    const int n = m_n;
    const std::size_t total = m_kernels.size();
    check_weights(weights, total);
    check_cotangents(cotangents, weights.size(), n);
    if constexpr (std::is_same_v<Float, float>) {
        adjoint_planar(weights, shift_scale, cotangents, gradient);
        return;
    }
    gradient.weight.assign(weights.size(), std::vector<std::complex<double>>(total, 0.0));
    gradient.shift_x.assign(total, 0.0);
    gradient.shift_y.assign(total, 0.0);
    const Kept* cached = kept(shift_scale);
    const Eigen::Index chunk = cached ? std::max<Eigen::Index>(Eigen::Index(total), 1)
                                      : chunk_size(n, sizeof(Complex), 4, kAdjointChunkColumns);
    const Eigen::Index cols = std::min<Eigen::Index>(chunk, std::max<Eigen::Index>(Eigen::Index(total), 1));
    ComplexMatrix<Float> built_xs, built_ys, z, v;
    allocating("the " + std::to_string(n) + "x" + std::to_string(n) + " slice's adjoint factor matrices",
               (cached ? 2.0 : 4.0) * double(n) * double(cols) * sizeof(Complex), [&] {
                   if (!cached) {
                       built_xs.resize(n, cols);
                       built_ys.resize(n, cols);
                   }
                   z.resize(n, cols);
                   v.resize(n, cols);
               });
    const ComplexMatrix<Float>& xs = cached ? cached->xs : built_xs;
    const ComplexMatrix<Float>& ys = cached ? cached->ys : built_ys;
    const double gauss = 2.0 * k_pi * k_pi * m_kernels.sigma_um * m_kernels.sigma_um;
    const double shift = shift_scale * 2.0 / m_lambda_um;
    std::vector<std::complex<double>> tx(static_cast<std::size_t>(cols)), ty(static_cast<std::size_t>(cols));
    for (Eigen::Index k0 = 0; k0 < Eigen::Index(total); k0 += chunk) {
        const Eigen::Index count = std::min<Eigen::Index>(chunk, Eigen::Index(total) - k0);
        const Eigen::Index base = cached ? k0 : 0;
        if (!cached)
            build_factors<Float>(m_kernels, m_grid, phases(), m_lambda_um, shift_scale, k0, count, built_xs, built_ys);
        std::fill(tx.begin(), tx.end(), 0.0);
        std::fill(ty.begin(), ty.end(), 0.0);
        for (std::size_t vec = 0; vec < weights.size(); ++vec) {
            const ComplexMatrix<Float>& b = cotangents[vec];
            // Z = B·Y and V = Bᵀ·X, split over kernels (columns).
            for_column_blocks(count, 2.0 * double(n) * n * double(count), [&](long long first, long long block) {
                z.middleCols(first, block).noalias() = b * ys.middleCols(base + first, block);
                v.middleCols(first, block).noalias() = b.transpose() * xs.middleCols(base + first, block);
            });
            RegionGuard guard;
#pragma omp parallel for schedule(static) if (worth_parallel(static_cast <long long>(count) * n))
            for (Eigen::Index c = 0; c < count; ++c)
                guard.run([&] {
                    const std::size_t idx = static_cast<std::size_t>(k0 + c);
                    const double bx = shift * m_kernels.slope_x[idx];
                    const double by = shift * m_kernels.slope_y[idx];
                    std::complex<double> t0 = 0.0, t1 = 0.0, t2 = 0.0;
                    for (Eigen::Index p = 0; p < n; ++p) {
                        const std::complex<double> xz = std::complex<double>(xs(p, base + c)) *
                                                        std::complex<double>(z(p, c));
                        t0 += xz;
                        t1 += -2.0 * gauss * (m_grid.ux[static_cast<std::size_t>(p)] + bx) * xz;
                        t2 += -2.0 * gauss * (m_grid.uy[static_cast<std::size_t>(p)] + by) *
                              (std::complex<double>(ys(p, base + c)) * std::complex<double>(v(p, c)));
                    }
                    const std::complex<double> w = weights[vec][idx];
                    gradient.weight[vec][idx] = t0;
                    tx[static_cast<std::size_t>(c)] += w * t1;
                    ty[static_cast<std::size_t>(c)] += w * t2;
                });
            guard.rethrow();
        }
        for (Eigen::Index c = 0; c < count; ++c) {
            const std::size_t idx = static_cast<std::size_t>(k0 + c);
            gradient.shift_x[idx] = 2.0 * std::real(tx[static_cast<std::size_t>(c)]);
            gradient.shift_y[idx] = 2.0 * std::real(ty[static_cast<std::size_t>(c)]);
        }
    }
}

// Single precision: the products as three real ones on planar operands (PlanarFactors).
// Forward, per weight vector: W = Y·diag(w_v) in planar form, then
//   F_re = X_re W_reᵀ − X_im W_imᵀ,  F_im = X_sum W_sumᵀ − X_re W_reᵀ − X_im W_imᵀ.
template <typename Float>
void SeparableEngine<Float>::forward_planar(const KernelWeights& weights, double shift_scale,
                                            std::vector<ComplexMatrix<Float>>& fields) {
    if constexpr (std::is_same_v<Float, float>) {
        using Complex = std::complex<float>;
        const int n = m_n;
        const Eigen::Index total = static_cast<Eigen::Index>(m_kernels.size());
        check_weights(weights, m_kernels.size());
        const std::string size = std::to_string(n) + "x" + std::to_string(n);
        fields.resize(weights.size());
        allocating("the " + size + " slice's " + std::to_string(weights.size()) + " field(s)",
                   double(weights.size()) * double(n) * n * sizeof(Complex), [&] {
                       for (ComplexMatrix<float>& f : fields) f.setZero(n, n);
                   });
        PlanarChunk factors;
        factors.cached = kept(shift_scale);
        const bool cached = factors.cached != nullptr;
        const Eigen::Index chunk = cached ? std::max<Eigen::Index>(total, 1) : chunk_size(n, sizeof(Complex), 3);
        const Eigen::Index cols = std::min(chunk, std::max<Eigen::Index>(total, 1));
        PlanarFactors yw;
        Eigen::MatrixXf fr, fi, scratch;
        allocating(
            "the " + size + " slice's factor matrices",
            (cached ? 1.5 : 4.5) * double(n) * double(cols) * sizeof(Complex) + 3.0 * double(n) * n * sizeof(float),
            [&] {
                factors.reserve(n, cols);
                yw.resize(n, cols);
                fr.resize(n, n);
                fi.resize(n, n);
                scratch.resize(n, n);
            });
        const PlanarFactors& xs = factors.x();
        const PlanarFactors& ys = factors.y();
        for (Eigen::Index k0 = 0; k0 < total; k0 += chunk) {
            const Eigen::Index count = std::min(chunk, total - k0);
            const Eigen::Index base = load_chunk(shift_scale, k0, count, factors);
            for (std::size_t v = 0; v < weights.size(); ++v) {
                // Y·diag(w_v): the weights enter the smaller factor.
                for (Eigen::Index c = 0; c < count; ++c) {
                    const std::complex<double> w = weights[v][static_cast<std::size_t>(k0 + c)];
                    const float wr = float(w.real()), wi = float(w.imag());
                    yw.re.col(c) = ys.re.col(base + c) * wr - ys.im.col(base + c) * wi;
                    yw.im.col(c) = ys.re.col(base + c) * wi + ys.im.col(base + c) * wr;
                    yw.sum.col(c) = yw.re.col(c) + yw.im.col(c);
                }
                ComplexMatrix<float>& field = fields[v];
                for_column_blocks(n, 0.75 * double(n) * n * double(count), [&](long long first, long long block) {
                    auto re = fr.middleCols(first, block);
                    auto im = fi.middleCols(first, block);
                    auto p2 = scratch.middleCols(first, block);
                    re.noalias() = xs.re.middleCols(base, count) *
                                   yw.re.leftCols(count).middleRows(first, block).transpose();
                    p2.noalias() = xs.im.middleCols(base, count) *
                                   yw.im.leftCols(count).middleRows(first, block).transpose();
                    im.noalias() = xs.sum.middleCols(base, count) *
                                   yw.sum.leftCols(count).middleRows(first, block).transpose();
                    im -= re;
                    im -= p2;
                    re -= p2;
                    field.middleCols(first, block).real() += re;
                    field.middleCols(first, block).imag() += im;
                });
            }
        }
        if (m_keep && !cached && total > 0 && total <= chunk) {
            for (PlanarFactors* p : {&factors.planar_x, &factors.planar_y}) {
                p->re.conservativeResize(n, total);
                p->im.conservativeResize(n, total);
                p->sum.conservativeResize(n, total);
            }
            keep(shift_scale, factors.planar_x, factors.planar_y);
        }
    } else {
        (void)weights;
        (void)shift_scale;
        (void)fields;
        throw std::logic_error("SeparableEngine: the planar path is single precision only");
    }
}

// Single precision: Z = B·Y and V = Bᵀ·X as three real products each (planar B, X, Y), then the
// per-kernel sums of the adjoint (separable_engine.h) in double.
template <typename Float>
void SeparableEngine<Float>::adjoint_planar(const KernelWeights& weights, double shift_scale,
                                            const std::vector<ComplexMatrix<Float>>& cotangents,
                                            FieldGradient& gradient) {
    if constexpr (std::is_same_v<Float, float>) {
        using Complex = std::complex<float>;
        const int n = m_n;
        const std::size_t total = m_kernels.size();
        gradient.weight.assign(weights.size(), std::vector<std::complex<double>>(total, 0.0));
        gradient.shift_x.assign(total, 0.0);
        gradient.shift_y.assign(total, 0.0);
        PlanarChunk factors;
        factors.cached = kept(shift_scale);
        const bool cached = factors.cached != nullptr;
        const Eigen::Index chunk = cached ? std::max<Eigen::Index>(Eigen::Index(total), 1)
                                          : chunk_size(n, sizeof(Complex), 4, kAdjointChunkColumns);
        const Eigen::Index cols = std::min<Eigen::Index>(chunk, std::max<Eigen::Index>(Eigen::Index(total), 1));
        PlanarFactors b;
        Eigen::MatrixXf zr, zi, vr, vi, scratch;
        allocating(
            "the " + std::to_string(n) + "x" + std::to_string(n) + " slice's adjoint factor matrices",
            (cached ? 2.5 : 5.5) * double(n) * double(cols) * sizeof(Complex) + 1.5 * double(n) * n * sizeof(Complex),
            [&] {
                factors.reserve(n, cols);
                b.resize(n, n);
                zr.resize(n, cols);
                zi.resize(n, cols);
                vr.resize(n, cols);
                vi.resize(n, cols);
                scratch.resize(n, cols);
            });
        const PlanarFactors& xs = factors.x();
        const PlanarFactors& ys = factors.y();
        const double gauss = 2.0 * k_pi * k_pi * m_kernels.sigma_um * m_kernels.sigma_um;
        const double shift = shift_scale * 2.0 / m_lambda_um;
        std::vector<std::complex<double>> tx(static_cast<std::size_t>(cols)), ty(static_cast<std::size_t>(cols));
        const Eigen::Map<const Eigen::VectorXd> ux(m_grid.ux.data(), n), uy(m_grid.uy.data(), n);
        for (Eigen::Index k0 = 0; k0 < Eigen::Index(total); k0 += chunk) {
            const Eigen::Index count = std::min<Eigen::Index>(chunk, Eigen::Index(total) - k0);
            const Eigen::Index base = load_chunk(shift_scale, k0, count, factors);
            std::fill(tx.begin(), tx.end(), 0.0);
            std::fill(ty.begin(), ty.end(), 0.0);
            for (std::size_t vec = 0; vec < weights.size(); ++vec) {
                b.assign(cotangents[vec], n);
                // Z = B·Y and V = Bᵀ·X, split over kernels (columns).
                for_column_blocks(count, 1.5 * double(n) * n * double(count), [&](long long first, long long block) {
                    auto p2 = scratch.middleCols(first, block);
                    auto z_re = zr.middleCols(first, block), z_im = zi.middleCols(first, block);
                    z_re.noalias() = b.re * ys.re.middleCols(base + first, block);
                    p2.noalias() = b.im * ys.im.middleCols(base + first, block);
                    z_im.noalias() = b.sum * ys.sum.middleCols(base + first, block);
                    z_im -= z_re;
                    z_im -= p2;
                    z_re -= p2;
                    auto v_re = vr.middleCols(first, block), v_im = vi.middleCols(first, block);
                    v_re.noalias() = b.re.transpose() * xs.re.middleCols(base + first, block);
                    p2.noalias() = b.im.transpose() * xs.im.middleCols(base + first, block);
                    v_im.noalias() = b.sum.transpose() * xs.sum.middleCols(base + first, block);
                    v_im -= v_re;
                    v_im -= p2;
                    v_re -= p2;
                });
                // Per kernel, in float on whole columns (vectorised): u + b in double, then
                // rounded once (it is small near the Gaussian's centre, where X is large).
                RegionGuard guard;
#pragma omp parallel if (worth_parallel(static_cast <long long>(count) * n))
                {
                    Eigen::ArrayXf xzr, xzi, yvr, yvi, fx, fy;
                    guard.run([&] {
                        for (Eigen::ArrayXf* a : {&xzr, &xzi, &yvr, &yvi, &fx, &fy}) a->resize(n);
                    });
#pragma omp for schedule(static)
                    for (Eigen::Index c = 0; c < count; ++c)
                        guard.run([&] {
                            const std::size_t idx = static_cast<std::size_t>(k0 + c);
                            const double bx = shift * m_kernels.slope_x[idx];
                            const double by = shift * m_kernels.slope_y[idx];
                            const auto x_re = xs.re.col(base + c).array(), x_im = xs.im.col(base + c).array();
                            const auto y_re = ys.re.col(base + c).array(), y_im = ys.im.col(base + c).array();
                            const auto z_re = zr.col(c).array(), z_im = zi.col(c).array();
                            const auto v_re = vr.col(c).array(), v_im = vi.col(c).array();
                            xzr = x_re * z_re - x_im * z_im;
                            xzi = x_re * z_im + x_im * z_re;
                            yvr = y_re * v_re - y_im * v_im;
                            yvi = y_re * v_im + y_im * v_re;
                            fx = (ux.array() + bx).cast<float>();
                            fy = (uy.array() + by).cast<float>();
                            const std::complex<double> t0(double(xzr.sum()), double(xzi.sum()));
                            const std::complex<double> t1(double((fx * xzr).sum()), double((fx * xzi).sum()));
                            const std::complex<double> t2(double((fy * yvr).sum()), double((fy * yvi).sum()));
                            const std::complex<double> w = weights[vec][idx];
                            gradient.weight[vec][idx] = t0;
                            tx[static_cast<std::size_t>(c)] += w * (-2.0 * gauss * t1);
                            ty[static_cast<std::size_t>(c)] += w * (-2.0 * gauss * t2);
                        });
                }
                guard.rethrow();
            }
            for (Eigen::Index c = 0; c < count; ++c) {
                const std::size_t idx = static_cast<std::size_t>(k0 + c);
                gradient.shift_x[idx] = 2.0 * std::real(tx[static_cast<std::size_t>(c)]);
                gradient.shift_y[idx] = 2.0 * std::real(ty[static_cast<std::size_t>(c)]);
            }
        }
    } else {
        (void)weights;
        (void)shift_scale;
        (void)cotangents;
        (void)gradient;
        throw std::logic_error("SeparableEngine: the planar path is single precision only");
    }
}

template class SeparableEngine<float>;
template class SeparableEngine<double>;

}  // namespace wavebrdf::detail
