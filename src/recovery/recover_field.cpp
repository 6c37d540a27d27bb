// Stage 1 of the recovery: the ptychographic field model (the Gabor field at zero slope) and
// phase retrieval of the object O = e^{−i(4π/λ)H} from the slices of overlapping footprints.
//
// For one footprint the model is a product of small matrices, as in the separable renderer
// (brdf_separable.cpp), but per texel row / column instead of per kernel, because with
// a_k = 0 the kernel factor X[p,k] depends on the kernel only through its row's offset δ_x:
//   I = X · (P ⊙ O_fp) · Yᵀ,  X[p,r] = exp(−2π²σ²u_x[p]²) e^{−i2π u_x[p] δ_x[r]},
// O_fp the object on the footprint's rows × columns and P the window c·w² (0 beyond 3σ_p).
// Its adjoint is Xᴴ · G · conj(Y), masked by P and scattered back onto the tile.
//
// X itself is not stored per footprint: with the footprint's rows in offset order (δ_r = δ_0 +
// r·d) and u_p = u_first + p·du, X[p, r] = φ_p E[p, r mod q] ψ_r with the footprint's own
// phase φ_p = e^{−i2π u_p δ_0}, E[p, j] = env(u_p) e^{−i2π p j du d} and ψ_r =
// e^{−i2π u_first r d}; E and ψ depend only on the u grid, d and the row count, and are shared
// by the ~700 footprints of a wavelength (AxisFactors). When q·du·d is an integer for some
// q < rows, rows q apart see the same phase at every pixel: they are summed first ("folded")
// and E has q columns. The window is separable (a Gaussian) cut to a disk: per footprint two
// vectors and each row's run of columns. The retrieval drops Φ: it changes no |Ψ| and cancels
// in the adjoint of an amplitude loss.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include <fftw3.h>
#include <omp.h>

#include "core/stall_rule.h"
#include "core/fftw_planner.h"
#include "wavebrdf/constants.h"
#include "wavebrdf/gabor.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/recover.h"
#include "wavebrdf/text.h"
#include "core/exact_sum.h"
#include "core/parallel.h"
#include "recovery/amplitude_loss.h"
#include "recovery/field_operator_detail.h"
#include "surface/footprint_offsets.h"

namespace wavebrdf {

namespace {

// Slice rows / columns whose envelope is below this (relative to its peak 1) are left out of
// the products: the model's field there is below 1e-16 of the footprint's.
constexpr double kEnvelopeCut = 1e-16;

// A 2-D complex FFT in place on a rows × cols row-major array, as row FFTs then column FFTs,
// each pass split over the threads (one FFTW plan per thread block; FFTW plans of disjoint
// blocks run concurrently). The retrieval runs two per evaluation on a grid of ~3e5 samples:
// on one thread they held the other core idle for a third of the field stage.
class SplitFft2d {
public:
    SplitFft2d(int rows, int cols, std::complex<double>* data, int sign) {
        const int threads = detail::in_parallel_region() ? 1 : std::max(1, omp_get_max_threads());
        auto* d = reinterpret_cast<fftw_complex*>(data);
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        for (int t = 0; t < threads; ++t) {
            const int r0 = rows * t / threads, r1 = rows * (t + 1) / threads;
            const int c0 = cols * t / threads, c1 = cols * (t + 1) / threads;
            if (r1 > r0)
                m_plans.push_back(fftw_plan_many_dft(1, &cols, r1 - r0, d + std::size_t(r0) * cols, nullptr, 1, cols,
                                                     d + std::size_t(r0) * cols, nullptr, 1, cols, sign,
                                                     FFTW_ESTIMATE));
            if (c1 > c0)
                m_column_plans.push_back(fftw_plan_many_dft(1, &rows, c1 - c0, d + c0, nullptr, cols, 1, d + c0,
                                                            nullptr, cols, 1, sign, FFTW_ESTIMATE));
        }
    }
    ~SplitFft2d() {
        std::lock_guard<std::mutex> lock(detail::fftw_planner_mutex());
        for (fftw_plan p : m_plans) fftw_destroy_plan(p);
        for (fftw_plan p : m_column_plans) fftw_destroy_plan(p);
    }
    SplitFft2d(const SplitFft2d&) = delete;
    SplitFft2d& operator=(const SplitFft2d&) = delete;

    void execute() const {
        run(m_plans);
        run(m_column_plans);
    }

private:
    static void run(const std::vector<fftw_plan>& plans) {
        const int n = int(plans.size());
#pragma omp parallel for schedule(static) num_threads(n) if (n > 1)
        for (int t = 0; t < n; ++t) fftw_execute(plans[std::size_t(t)]);
    }
    std::vector<fftw_plan> m_plans, m_column_plans;
};

// The flat grid (rows × cols zeros, texels of texel_um) a footprint is taken on: the same for
// every footprint of a tile, so the last one built is shared for as long as someone holds it
// (retrieve_field holds it while it builds a wavelength's ~700 operators; building it per
// operator, 2.6 MB validated and page-faulted each, was most of the ~0.4 s that took).
std::shared_ptr<const Heightfield> shared_flat_grid(int rows, int cols, double texel_um) {
    static std::mutex mutex;
    static std::weak_ptr<const Heightfield> last;
    std::lock_guard<std::mutex> lock(mutex);
    std::shared_ptr<const Heightfield> kept = last.lock();
    if (kept && kept->rows() == rows && kept->cols() == cols && kept->texel_um() == texel_um) return kept;
    kept = std::make_shared<const Heightfield>(rows, cols, std::vector<double>(std::size_t(rows) * cols, 0.0),
                                               texel_um);
    last = kept;
    return kept;
}

}  // namespace

namespace {

// A complex single-precision matrix as its real and imaginary parts and their sum: the operand
// of product3 (the field stage's products).
struct Planar {
    Eigen::MatrixXf re, im, sum;
    Planar() = default;
    explicit Planar(const Eigen::MatrixXcf& m) : re(m.real()), im(m.imag()), sum(re + im) {}
    void set_sum() { sum = re + im; }
};

// c = a · b in planar form with three real products instead of a complex one (Gauss):
//   P1 = a_re b_re, P2 = a_im b_im, P3 = (a_re + a_im)(b_re + b_im);
//   c_re = P1 − P2, c_im = P3 − P1 − P2.
// Both operands' sums must be set. At the field stage's sizes (48 × 72 × 72, 48 × 81 × 81) the
// three real float products took ~20 % less CPU than Eigen's complex float product
// (experiments/2026-11-23-recovery-speed.md). The imaginary part's rounding scales with |a||b| rather
// than |c_im|: a few float ulps of the operands' scale, far below the retrieval's loss floor
// (~1e-3 relative).
void product3(const Planar& a, const Planar& b, Planar& c, Eigen::MatrixXf& scratch) {
    c.re.noalias() = a.re * b.re;
    scratch.noalias() = a.im * b.im;
    c.im.noalias() = a.sum * b.sum;
    c.im -= c.re;
    c.im -= scratch;
    c.re -= scratch;
}

// One axis (slice rows, or columns) of the field model, shared by every footprint with the
// same u grid (ω_i, λ, resolution, envelope), fine-grid spacing d and footprint row count.
// With the footprint's rows in offset order, δ_r = δ_0 + r·d, and u_p = u_first + p·du:
//   X[p, r] = env(u_p) e^{−i2π u_p δ_r} = φ_p · E[p, r mod q] · ψ_r,
//   φ_p = e^{−i2π u_p δ_0} (the footprint's own diagonal phase), ψ_r = e^{−i2π u_first r d},
//   E[p, j] = env(u_p) e^{−i2π p j α},  α = du·d,
// exact when q·α is an integer: rows q apart then see the same phase at every pixel and are
// summed ("folded") before the product. The smallest such q ≤ count is used; q = count
// (nothing folded) when there is none.
struct AxisFactors {
    int first = 0, m = 0;                   // slice rows [first, first + m) in use
    int count = 0, q = 0;                   // footprint rows, fold period
    std::vector<double> u;                  // u_p (1/µm), p < m
    std::vector<std::complex<double>> psi;  // ψ_r, r < count
    Eigen::MatrixXcd e;                     // E: m × q
    // E in single precision, planar (product3): E, Eᵀ, Eᴴ and conj(E).
    Planar ef, ef_transpose, ef_adjoint, ef_conjugate;
};

// √c1 per slice pixel for one slice family (model, ω_i, λ, resolution), on the whole slice
// and on the pixel box the operators use.
struct SliceAmplitude {
    std::vector<double> full;
    Eigen::MatrixXd box;
};

// The last value made for `key`, shared for as long as someone holds it (the ~700 operators
// of a wavelength share a few); expired entries are dropped when a new one is made.
template <class Key, class Value, class Make>
std::shared_ptr<const Value> shared_value(const Key& key, Make make) {
    static std::mutex mutex;
    static std::map<Key, std::weak_ptr<const Value>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    const auto found = cache.find(key);
    if (found != cache.end())
        if (std::shared_ptr<const Value> kept = found->second.lock()) return kept;
    for (auto it = cache.begin(); it != cache.end();) it = it->second.expired() ? cache.erase(it) : std::next(it);
    std::shared_ptr<const Value> made = std::make_shared<const Value>(make());
    cache[key] = made;
    return made;
}

std::shared_ptr<const AxisFactors> axis_factors(double omega_i, double lambda_um, int resolution, double sigma_um,
                                                double spacing_um, int count) {
    using Key = std::tuple<double, double, int, double, double, int>;
    return shared_value<Key, AxisFactors>(Key{omega_i, lambda_um, resolution, sigma_um, spacing_um, count}, [&] {
        AxisFactors a;
        // Slice rows whose envelope exp(−2π²σ²u²) reaches kEnvelopeCut of its peak.
        const double gauss = 2.0 * k_pi * k_pi * sigma_um * sigma_um;
        a.first = resolution;
        int last = -1;
        for (int p = 0; p < resolution; ++p) {
            const double u = (omega_i + slice_omega(p, resolution)) / lambda_um;
            if (std::exp(-gauss * u * u) >= kEnvelopeCut) {
                a.first = std::min(a.first, p);
                last = p;
            }
        }
        a.m = std::max(0, last - a.first + 1);
        if (a.m == 0) a.first = 0;
        a.count = count;
        const double u_first = (omega_i + slice_omega(a.first, resolution)) / lambda_um;
        const double alpha = 2.0 / (resolution * lambda_um) * spacing_um;  // du·d
        a.q = count;
        for (int t = 1; t < count; ++t) {
            const double v = t * alpha;
            if (std::abs(v - std::round(v)) <= 1e-12 * std::max(1.0, v)) {
                a.q = t;
                break;
            }
        }
        a.psi.resize(std::size_t(count));
        for (int r = 0; r < count; ++r) a.psi[std::size_t(r)] = std::polar(1.0, -2.0 * k_pi * u_first * r * spacing_um);
        a.u.resize(std::size_t(a.m));
        a.e.resize(a.m, a.q);
        for (int p = 0; p < a.m; ++p) {
            const double u = (omega_i + slice_omega(a.first + p, resolution)) / lambda_um;
            a.u[std::size_t(p)] = u;
            const double env = std::exp(-gauss * u * u);
            for (int j = 0; j < a.q; ++j) a.e(p, j) = env * std::polar(1.0, -2.0 * k_pi * alpha * (double(p) * j));
        }
        const Eigen::MatrixXcf ef = a.e.cast<std::complex<float>>();
        a.ef = Planar(ef);
        a.ef_transpose = Planar(ef.transpose());
        a.ef_adjoint = Planar(ef.adjoint());
        a.ef_conjugate = Planar(ef.conjugate());
        return a;
    });
}

std::shared_ptr<const SliceAmplitude> slice_amplitude(const Query& query, double lambda_um, int resolution,
                                                      const AxisFactors& ax, const AxisFactors& ay) {
    using Key = std::tuple<int, double, double, double, int, int, int, int, int>;
    return shared_value<Key, SliceAmplitude>(
        Key{int(query.model), query.omega_i[0], query.omega_i[1], lambda_um, resolution, ax.first, ax.m, ay.first,
            ay.m},
        [&] {
            // f = c1 |I|² inside the disk (docs/model.md §5); the renderer writes non-finite
            // values as 0.
            SliceAmplitude s;
            s.full.assign(std::size_t(resolution) * resolution, 0.0);
            for (int p = 0; p < resolution; ++p) {
                for (const auto [q, ox, oy] : disk_row(p, resolution)) {
                    const double c1 = direction_factors(query.model, query.omega_i, ox, oy, lambda_um).c1;
                    if (std::isfinite(c1) && c1 > 0.0) s.full[std::size_t(p) * resolution + q] = std::sqrt(c1);
                }
            }
            s.box.resize(ax.m, ay.m);
            for (int p = 0; p < ax.m; ++p)
                for (int q = 0; q < ay.m; ++q)
                    s.box(p, q) = s.full[std::size_t(ax.first + p) * resolution + ay.first + q];
            return s;
        });
}

}  // namespace

// Per footprint: its rows / columns on the tile (in offset order), the window as a separable
// product cut to the 3σ_p disk (P[r, c] = wx[r]·wy[c] for c in [lo[r], hi[r]), else 0), the
// diagonal phases φ; the factor matrices are shared (AxisFactors). The forward map is
//   Ψ = Φx · Ex · F · Eyᵀ · Φy,  F[j, l] = Σ_{r ≡ j (qx), c ≡ l (qy)} ψx_r ψy_c P[r, c] O[r, c],
// and the retrieval drops Φx, Φy: they change no |Ψ| and cancel in the adjoint of a loss of |Ψ|
// (its gradient is a real weight times Ψ).
struct FieldOperator::Impl {
    int rows = 0, cols = 0, n = 0;
    std::vector<int> row_index, col_index;  // footprint texel rows / columns on the tile
    std::vector<double> wx, wy;             // the separable window
    std::vector<int> lo, hi;                // columns of row r inside the 3σ_p cut
    int col_wrap = 0;                       // first footprint column whose tile column wrapped to 0 (else their count)
    std::vector<std::complex<double>> px, py;            // wx·ψx, wy·ψy
    std::vector<std::complex<double>> phase_x, phase_y;  // φ on the box rows / columns
    std::shared_ptr<const AxisFactors> ax, ay;
    std::shared_ptr<const SliceAmplitude> amp;

    int a0() const { return ax->first; }
    int ma() const { return ax->m; }
    int b0() const { return ay->first; }
    int mb() const { return ay->m; }
    const Eigen::MatrixXd& amp_box() const { return amp->box; }

    template <class T>
    using RowMajor = Eigen::Matrix<std::complex<T>, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

    // Calls body(c, l, t, len) for the runs of row r's columns [lo, hi) along which the column
    // c, its fold slot l = c mod qy and its tile column t all step by one.
    template <class Body>
    void for_runs(std::size_t r, Body body) const {
        const int qy = ay->q;
        int c = lo[r], l = c % qy;
        while (c < hi[r]) {
            int len = std::min(hi[r] - c, qy - l);
            if (c < col_wrap) len = std::min(len, col_wrap - c);
            body(c, l, col_index[std::size_t(c)], len);
            c += len;
            l += len;
            if (l == qy) l = 0;
        }
    }

    // F (qx × qy) from the object (rows × cols, row-major).
    void fold(const std::complex<double>* object, RowMajor<double>& f) const {
        const int qx = ax->q, qy = ay->q;
        f.setZero(qx, qy);
        std::vector<std::complex<double>> line(std::size_t(std::max(qy, 0)));
        for (std::size_t r = 0; r < row_index.size(); ++r) {
            std::fill(line.begin(), line.end(), 0.0);
            const std::complex<double>* o = object + std::size_t(row_index[r]) * cols;
            for_runs(r, [&](int c, int l, int t, int len) {
                std::complex<double>* out = line.data() + l;
                const std::complex<double>* in = o + t;
                const std::complex<double>* w = py.data() + c;
                for (int k = 0; k < len; ++k) out[k] += in[k] * w[k];
            });
            std::complex<double>* row = f.data() + std::size_t(int(r) % qx) * std::size_t(qy);
            const std::complex<double> s = px[r];
            for (int l = 0; l < qy; ++l) row[l] += s * line[std::size_t(l)];
        }
    }
    // object += the adjoint of fold applied to B (qx × qy).
    template <class T>
    void unfold_add(const RowMajor<T>& b, std::complex<double>* object) const {
        const int qx = ax->q, qy = ay->q;
        for (std::size_t r = 0; r < row_index.size(); ++r) {
            std::complex<double>* o = object + std::size_t(row_index[r]) * cols;
            const std::complex<double> s = std::conj(px[r]);
            const std::complex<T>* row = b.data() + std::size_t(int(r) % qx) * std::size_t(qy);
            for_runs(r, [&](int c, int l, int t, int len) {
                std::complex<double>* out = o + t;
                const std::complex<T>* in = row + l;
                const std::complex<double>* w = py.data() + c;
                for (int k = 0; k < len; ++k) out[k] += s * (std::conj(w[k]) * std::complex<double>(in[k]));
            });
        }
    }
    // Whether Ex·(F·Eyᵀ) costs less than (Ex·F)·Eyᵀ (and likewise for the adjoint).
    bool right_first() const {
        const double qx = ax->q, qy = ay->q, mx = ax->m, my = ay->m;
        return qx * qy * my + mx * qx * my <= mx * qx * qy + mx * qy * my;
    }

    // Ψ without the diagonal phases Φx, Φy, on the box, in single precision (the retrieval's
    // inner loop; its phases need nowhere near double precision).
    // The products in planar form (product3); the operands and intermediates are kept per
    // thread between calls.
    struct Work {
        RowMajor<double> f;
        RowMajor<float> b;
        Planar x, t, y;
        Eigen::MatrixXf scratch;
    };
    static Work& work() {
        thread_local Work w;
        return w;
    }
    void forward_unphased(const std::complex<double>* object, Eigen::MatrixXcf& psi) const {
        Work& w = work();
        fold(object, w.f);
        const Eigen::Index qx = w.f.rows(), qy = w.f.cols();
        w.x.re.resize(qx, qy);
        w.x.im.resize(qx, qy);
        for (Eigen::Index j = 0; j < qx; ++j)
            for (Eigen::Index l = 0; l < qy; ++l) {
                w.x.re(j, l) = float(w.f(j, l).real());
                w.x.im(j, l) = float(w.f(j, l).imag());
            }
        w.x.set_sum();
        if (right_first()) {
            product3(w.x, ay->ef_transpose, w.t, w.scratch);
            w.t.set_sum();
            product3(ax->ef, w.t, w.y, w.scratch);
        } else {
            product3(ax->ef, w.x, w.t, w.scratch);
            w.t.set_sum();
            product3(w.t, ay->ef_transpose, w.y, w.scratch);
        }
        psi.resize(w.y.re.rows(), w.y.re.cols());
        psi.real() = w.y.re;
        psi.imag() = w.y.im;
    }
    // object += the adjoint of forward_unphased applied to G (on the box).
    void adjoint_unphased_add(const Eigen::MatrixXcf& g, std::complex<double>* object) const {
        Work& w = work();
        w.x.re = g.real();
        w.x.im = g.imag();
        w.x.set_sum();
        if (right_first()) {
            product3(ax->ef_adjoint, w.x, w.t, w.scratch);
            w.t.set_sum();
            product3(w.t, ay->ef_conjugate, w.y, w.scratch);
        } else {
            product3(w.x, ay->ef_conjugate, w.t, w.scratch);
            w.t.set_sum();
            product3(ax->ef_adjoint, w.t, w.y, w.scratch);
        }
        w.b.resize(w.y.re.rows(), w.y.re.cols());
        w.b.real() = w.y.re;
        w.b.imag() = w.y.im;
        unfold_add(w.b, object);
    }
    // Σ |P|² per object sample, added to `coverage` (rows × cols).
    // add(sample, |P|²) for every object sample of the window (its coverage of the tile).
    template <typename Add>
    void add_coverage(Add&& add) const {
        for (std::size_t r = 0; r < row_index.size(); ++r)
            for (int c = lo[r]; c < hi[r]; ++c) {
                const double p = wx[r] * wy[std::size_t(c)];
                add(std::size_t(row_index[r]) * cols + col_index[std::size_t(c)], p * p);
            }
    }
};

// Gives the retrieval loop access to the factor matrices.
struct FieldAccess {
    static const FieldOperator::Impl& impl(const FieldOperator& op) { return *op.m_impl; }
    // For detail::field_amplitude_box (field_operator_detail.h).
    static const Eigen::MatrixXd& amplitude_box(const FieldOperator& op, int& first_row, int& first_col) {
        first_row = op.m_impl->a0();
        first_col = op.m_impl->b0();
        return op.m_impl->amp_box();
    }
};

FieldOperator::FieldOperator(int rows, int cols, double texel_um, const Query& query, double lambda_um, int resolution,
                             int refine)
    : m_impl(std::make_unique<Impl>()) {
    if (refine < 1 || refine > 64)
        throw std::invalid_argument("object grid refinement " + std::to_string(refine) +
                                    " is invalid; expected 1 to 64");
    if (rows < 1 || cols < 1)
        throw std::invalid_argument("tile of " + std::to_string(rows) + " x " + std::to_string(cols) +
                                    " texels; expected at least 1 x 1");
    if (!std::isfinite(texel_um) || texel_um <= 0.0)
        throw std::domain_error("texel width " + format_shortest(texel_um) +
                                " um is invalid; expected a finite value > 0");
    validate(query);
    validate_lambda(lambda_um);
    validate_resolution(resolution);
    if (!is_separable(query.model))
        throw std::invalid_argument(std::string("model ") + to_string(query.model) +
                                    " has no field model; expected OHS or ROHS");
    Impl& s = *m_impl;
    s.rows = rows * refine;
    s.cols = cols * refine;
    s.n = resolution;

    // The footprint exactly as the renderer sees it on a grid `refine` times finer: the same
    // kernels, offsets and weights.
    const std::shared_ptr<const Heightfield> flat_grid = shared_flat_grid(s.rows, s.cols, texel_um / refine);
    const Heightfield& flat = *flat_grid;
    const double d = flat.texel_um();
    const detail::FootprintOffsets k = detail::footprint_offsets(flat, query.x_um, query.y_um, query.sigma_p_um);
    // The footprint's rows (columns) in offset order: the minimal periodic images of a regular
    // grid, so offset r is δ_0 + r·d.
    const auto axis = [&](const std::vector<int>& index, const std::vector<double>& offset, int size,
                          std::vector<int>& tile_index, std::vector<double>& sorted_offset, std::vector<int>& slot) {
        std::vector<std::pair<double, int>> seen;
        std::vector<char> taken(std::size_t(size), 0);
        for (std::size_t i = 0; i < index.size(); ++i)
            if (!taken[std::size_t(index[i])]) {
                taken[std::size_t(index[i])] = 1;
                seen.emplace_back(offset[i], index[i]);
            }
        std::sort(seen.begin(), seen.end());
        slot.assign(std::size_t(size), -1);
        for (std::size_t r = 0; r < seen.size(); ++r) {
            if (std::abs(seen[r].first - (seen[0].first + double(r) * d)) > 1e-9 * (d + std::abs(seen[r].first)))
                throw std::logic_error("FieldOperator: footprint offsets are not evenly spaced by the grid's " +
                                       format_shortest(d) + " um");
            sorted_offset.push_back(seen[r].first);
            tile_index.push_back(seen[r].second);
            slot[std::size_t(seen[r].second)] = int(r);
        }
    };
    std::vector<double> dx, dy;
    std::vector<int> slot_r, slot_c;
    axis(k.row, k.dx_um, s.rows, s.row_index, dx, slot_r);
    axis(k.col, k.dy_um, s.cols, s.col_index, dy, slot_c);
    const std::size_t nr = s.row_index.size(), nc = s.col_index.size();
    // Tile columns step by one along the footprint's columns, wrapping once at the border.
    s.col_wrap = int(nc);
    for (std::size_t c = 1; c < nc; ++c) {
        const int expected = (s.col_index[c - 1] + 1) % s.cols;
        if (s.col_index[c] != expected)
            throw std::logic_error("FieldOperator: the footprint's columns are not consecutive on the tile");
        if (s.col_index[c] == 0) s.col_wrap = int(c);
    }
    // The window c(δ) w² = c_x(δx) c_y(δy) (Gaussian), cut where |δ| > 3σ_p: on each row a run
    // of columns (the cut is a disk).
    s.lo.assign(nr, int(nc));
    s.hi.assign(nr, 0);
    std::vector<int> in_row(nr, 0);
    for (std::size_t i = 0; i < k.size(); ++i) {
        const std::size_t r = std::size_t(slot_r[std::size_t(k.row[i])]);
        const int c = slot_c[std::size_t(k.col[i])];
        s.lo[r] = std::min(s.lo[r], c);
        s.hi[r] = std::max(s.hi[r], c + 1);
        ++in_row[r];
    }
    for (std::size_t r = 0; r < nr; ++r) {
        if (in_row[r] != s.hi[r] - s.lo[r])
            throw std::logic_error("FieldOperator: the footprint's row " + std::to_string(r) +
                                   " is not one run of columns");
    }
    const double sp2 = 2.0 * query.sigma_p_um * query.sigma_p_um;
    s.wx.resize(nr);
    s.wy.resize(nc);
    for (std::size_t r = 0; r < nr; ++r) s.wx[r] = window_weight(dx[r] * dx[r], query.sigma_p_um) * d * d;
    for (std::size_t c = 0; c < nc; ++c) s.wy[c] = std::exp(-dy[c] * dy[c] / sp2);

    s.ax = axis_factors(query.omega_i[0], lambda_um, resolution, k.sigma_um, d, int(nr));
    s.ay = axis_factors(query.omega_i[1], lambda_um, resolution, k.sigma_um, d, int(nc));
    s.px.resize(nr);
    s.py.resize(nc);
    for (std::size_t r = 0; r < nr; ++r) s.px[r] = s.wx[r] * s.ax->psi[r];
    for (std::size_t c = 0; c < nc; ++c) s.py[c] = s.wy[c] * s.ay->psi[c];
    const auto phases = [](const AxisFactors& a, const std::vector<double>& offset) {
        std::vector<std::complex<double>> out(a.u.size(), 1.0);
        if (!offset.empty())
            for (std::size_t p = 0; p < a.u.size(); ++p) out[p] = std::polar(1.0, -2.0 * k_pi * a.u[p] * offset[0]);
        return out;
    };
    s.phase_x = phases(*s.ax, dx);
    s.phase_y = phases(*s.ay, dy);
    s.amp = slice_amplitude(query, lambda_um, resolution, *s.ax, *s.ay);
}

FieldOperator::~FieldOperator() = default;
FieldOperator::FieldOperator(FieldOperator&&) noexcept = default;
FieldOperator& FieldOperator::operator=(FieldOperator&&) noexcept = default;

std::vector<std::complex<double>> FieldOperator::forward(const std::vector<std::complex<double>>& object) const {
    const Impl& s = *m_impl;
    if (object.size() != std::size_t(s.rows) * s.cols)
        throw std::invalid_argument("object has " + std::to_string(object.size()) +
                                    " values; expected rows * cols = " + std::to_string(std::size_t(s.rows) * s.cols));
    Impl::RowMajor<double> f;
    s.fold(object.data(), f);
    const Eigen::MatrixXcd psi = s.ax->e * f * s.ay->e.transpose();
    std::vector<std::complex<double>> field(std::size_t(s.n) * s.n, 0.0);
    for (int p = 0; p < s.ma(); ++p)
        for (int q = 0; q < s.mb(); ++q)
            field[std::size_t(s.a0() + p) * s.n + s.b0() + q] = s.phase_x[std::size_t(p)] * s.phase_y[std::size_t(q)] *
                                                                psi(p, q);
    return field;
}

std::vector<std::complex<double>> FieldOperator::adjoint(const std::vector<std::complex<double>>& field) const {
    const Impl& s = *m_impl;
    if (field.size() != std::size_t(s.n) * s.n)
        throw std::invalid_argument("field has " + std::to_string(field.size()) +
                                    " values; expected resolution^2 = " + std::to_string(std::size_t(s.n) * s.n));
    Eigen::MatrixXcd g(s.ma(), s.mb());
    for (int p = 0; p < s.ma(); ++p)
        for (int q = 0; q < s.mb(); ++q)
            g(p, q) = std::conj(s.phase_x[std::size_t(p)] * s.phase_y[std::size_t(q)]) *
                      field[std::size_t(s.a0() + p) * s.n + s.b0() + q];
    const Impl::RowMajor<double> b = s.ax->e.adjoint() * g * s.ay->e.conjugate();
    std::vector<std::complex<double>> object(std::size_t(s.rows) * s.cols, 0.0);
    s.unfold_add(b, object.data());
    return object;
}

const std::vector<double>& FieldOperator::amplitude_factor() const { return m_impl->amp->full; }

namespace detail {
void field_forward_unphased(const FieldOperator& op, const std::complex<double>* object, Eigen::MatrixXcf& psi) {
    FieldAccess::impl(op).forward_unphased(object, psi);
}
void field_adjoint_unphased_add(const FieldOperator& op, const Eigen::MatrixXcf& g, std::complex<double>* object) {
    FieldAccess::impl(op).adjoint_unphased_add(g, object);
}
const Eigen::MatrixXd& field_amplitude_box(const FieldOperator& op, int& first_row, int& first_col) {
    return FieldAccess::amplitude_box(op, first_row, first_col);
}
const std::vector<int>& field_rows(const FieldOperator& op) { return FieldAccess::impl(op).row_index; }
const std::vector<int>& field_cols(const FieldOperator& op) { return FieldAccess::impl(op).col_index; }
}  // namespace detail
int FieldOperator::resolution() const { return m_impl->n; }

std::vector<double> refined_heights(const Heightfield& hf, int refine) {
    if (refine < 1 || refine % 2 == 0)
        throw std::invalid_argument("refine " + std::to_string(refine) + " is invalid; expected an odd value >= 1");
    const int rows = hf.rows() * refine, cols = hf.cols() * refine;
    const double w = hf.texel_um(), d = w / refine, sigma = 0.5 * w;
    std::vector<double> out(std::size_t(rows) * cols);
    // Kernels within 3 texels (≥ 6σ) of a sample contribute; the rest are below e^{-18}.
    constexpr int reach = 3, side = 2 * reach + 1;
    // The Gaussian of kernel (di, dj) depends only on the sample's place inside its texel: one
    // table of refine² × 7² values (each rounded as the per-sample expression was, so the same
    // bits) instead of 49 exps per sample.
    std::vector<double> gauss(std::size_t(refine) * refine * side * side);
    for (int ra = 0; ra < refine; ++ra)
        for (int rb = 0; rb < refine; ++rb) {
            const double ox = (ra - refine / 2) * d, oy = (rb - refine / 2) * d;
            for (int di = -reach; di <= reach; ++di) {
                const double dx = ox - di * w, dx2 = dx * dx;
                for (int dj = -reach; dj <= reach; ++dj) {
                    const double dy = oy - dj * w;
                    // exp(−(dx² + dy²)/(2σ²)) rounded as the per-sample loop it replaces was
                    // compiled (dx² rounded outside the dj loop, dy² fused with it): the same bits.
#ifdef __FMA__
                    const double r2 = std::fma(dy, dy, dx2);
#else
                    const double r2 = dy * dy + dx2;
#endif
                    gauss[((std::size_t(ra) * refine + rb) * side + std::size_t(di + reach)) * side + (dj + reach)] =
                        std::exp(-r2 / (2.0 * sigma * sigma));
                }
            }
        }
    // The values with a periodic border of reach + 1 (the slopes' neighbours): no index wrapping
    // per kernel. Heights and slopes are formed from them as Heightfield::height_um and slope do.
    constexpr int pad = reach + 1;
    const int padded_cols = hf.cols() + 2 * pad;
    std::vector<double> values(std::size_t(hf.rows() + 2 * pad) * padded_cols);
    for (int i = -pad; i < hf.rows() + pad; ++i)
        for (int j = -pad; j < hf.cols() + pad; ++j)
            values[std::size_t(i + pad) * padded_cols + (j + pad)] = hf.value(i, j);
    const double vscale = hf.vscale();
    detail::RegionGuard guard;
#pragma omp parallel for schedule(static) if (std::size_t(rows) * cols > 4096)
    for (int a = 0; a < rows; ++a)
        guard.run([&] {
            for (int b = 0; b < cols; ++b) {
                const int i0 = a / refine, j0 = b / refine;
                const int ra = a - i0 * refine, rb = b - j0 * refine;
                // Offset of the sample from its texel's centre (µm).
                const double ox = (ra - refine / 2) * d, oy = (rb - refine / 2) * d;
                const double* g_row = &gauss[(std::size_t(ra) * refine + rb) * side * side];
                double num = 0.0, den = 0.0;
                for (int di = -reach; di <= reach; ++di) {
                    // Row i0 + di of the padded values, and its neighbours' rows.
                    const double* v = &values[std::size_t(i0 + di + pad) * padded_cols + pad];
                    const double* v_up = v + padded_cols;
                    const double* v_down = v - padded_cols;
                    for (int dj = -reach; dj <= reach; ++dj) {
                        const double dx = ox - di * w, dy = oy - dj * w;  // x − μ_k
                        const double g = g_row[(di + reach) * side + (dj + reach)];
                        const int j = j0 + dj;
                        const std::array<double, 2> s{0.5 * vscale * (v_up[j] - v_down[j]),
                                                      0.5 * vscale * (v[j + 1] - v[j - 1])};
                        // The expression of Heightfield::height_um and slope, inlined as before
                        // (the same contractions: estimate_height.npy byte for byte, recovery.md).
                        num += g * (vscale * w * v[j] + s[0] * dx + s[1] * dy);
                        den += g;
                    }
                }
                out[std::size_t(a) * cols + b] = num / den;
            }
        });
    guard.rethrow();
    return out;
}

std::vector<std::complex<double>> object_from_heights(const Heightfield& hf, double lambda_um, int refine) {
    validate_lambda(lambda_um);
    const std::vector<double> h = refined_heights(hf, refine);
    std::vector<std::complex<double>> object(h.size());
    for (std::size_t k = 0; k < h.size(); ++k) object[k] = std::polar(1.0, -4.0 * k_pi / lambda_um * h[k]);
    return object;
}

// ---- phase retrieval -------------------------------------------------------------------------

FieldRetrievalResult retrieve_field(const std::vector<Observation>& observations, double lambda_um, int rows, int cols,
                                    double texel_um, const std::vector<std::complex<double>>& initial,
                                    const FieldRetrievalSettings& settings,
                                    const std::function<bool(int, double)>& on_iteration, const Communicator& comm) {
    std::vector<const Observation*> pointers(observations.size());
    for (std::size_t i = 0; i < observations.size(); ++i) pointers[i] = &observations[i];
    return retrieve_field(pointers, lambda_um, rows, cols, texel_um, initial, settings, on_iteration, comm);
}

namespace {

// One observation of the retrieval: its operator on the fine grid and its reference.
struct RetrievalSlice {
    FieldOperator op;
    Eigen::MatrixXf sqrt_ref;  // √R on the operator's box
    Eigen::MatrixXf weight;    // the pixel weights on the box (empty: the observation has none)
    double outside = 0.0;      // Σ w R beyond the box (the model is 0 there)
};

// The retrieval's arguments, checked before anything is built (the same checks on every rank).
void check_retrieval(const std::vector<const Observation*>& observations, double lambda_um, int rows, int cols,
                     const std::vector<std::complex<double>>& initial, const FieldRetrievalSettings& settings,
                     const Communicator& comm) {
    for (std::size_t i = 0; i < observations.size(); ++i)
        if (observations[i] == nullptr)
            throw std::invalid_argument("retrieve_field: observation " + std::to_string(i) +
                                        " is null; expected a pointer to an observation");
    // Under MPI `observations` is this rank's share (it may be empty); every sum over the
    // observations below is allreduced.
    {
        std::vector<double> count{double(observations.size())};
        if (comm.size() > 1) comm.allreduce_sum(count);
        if (count[0] == 0.0) throw std::invalid_argument("retrieve_field: no observations given");
    }
    validate_lambda(lambda_um);
    if (settings.refine < 1 || settings.refine > 64)
        throw std::invalid_argument("retrieve_field: refine " + std::to_string(settings.refine) +
                                    " is invalid; expected 1 to 64");
    const int q = settings.refine;
    const std::size_t texels = std::size_t(rows) * q * std::size_t(std::max(cols, 0)) * q;
    if (!initial.empty() && initial.size() != texels)
        throw std::invalid_argument("retrieve_field: initial object has " + std::to_string(initial.size()) +
                                    " values; expected (rows * refine) * (cols * refine) = " + std::to_string(texels));
    if (settings.iterations < 0 || settings.history < 1)
        throw std::domain_error("retrieve_field: iterations " + std::to_string(settings.iterations) + " / history " +
                                std::to_string(settings.history) + " invalid; expected >= 0 / >= 1");
    if (settings.stall_window < 0 || !(settings.stall_tolerance >= 0.0) || !std::isfinite(settings.stall_tolerance))
        throw std::domain_error("retrieve_field: stall window " + std::to_string(settings.stall_window) +
                                " / tolerance " + format_shortest(settings.stall_tolerance) +
                                " invalid; expected >= 0 / finite >= 0");
    run_agreed(comm, [&] {
        for (std::size_t i = 0; i < observations.size(); ++i) {
            const Observation& o = *observations[i];
            validate(o, i);
            if (o.lambdas_um.size() != 1 || std::abs(o.lambdas_um[0] - lambda_um) > 1e-12 * lambda_um)
                throw std::invalid_argument("retrieve_field: observation " + std::to_string(i) +
                                            " is not a single-wavelength slice at " + format_shortest(lambda_um) +
                                            " um");
        }
    });
}

// Each observation's operator on the fine grid and √R on its box. The operators are independent
// of each other: built on all threads (each builds its footprint on the fine grid, the costliest
// set-up step), kept in order. `total`: Σ R over every rank's slices.
std::vector<RetrievalSlice> build_retrieval_slices(const std::vector<const Observation*>& observations,
                                                   double lambda_um, int rows, int cols, double texel_um, int q,
                                                   const Communicator& comm, double& total) {
    std::vector<std::unique_ptr<RetrievalSlice>> built(observations.size());
    std::vector<double> totals(observations.size(), 0.0);
    {
        detail::RegionGuard guard;
#pragma omp parallel for schedule(dynamic) if (observations.size() > 1 && !detail::in_parallel_region())
        for (std::size_t i = 0; i < observations.size(); ++i)
            guard.run([&] {
                const Observation& o = *observations[i];
                auto s = std::make_unique<RetrievalSlice>(RetrievalSlice{
                    FieldOperator(rows, cols, texel_um, o.query, lambda_um, o.resolution, q), {}, {}, 0.0});
                const auto& impl = FieldAccess::impl(s->op);
                s->sqrt_ref.resize(impl.ma(), impl.mb());
                if (!o.weights.empty()) s->weight.resize(impl.ma(), impl.mb());
                const int n = o.resolution;
                double sum = 0.0;
                for (int p = 0; p < n; ++p)
                    for (int c = 0; c < n; ++c) {
                        const std::size_t k = std::size_t(p) * n + c;
                        // A pixel of weight 0 enters nothing (its value may be anything).
                        const float w = o.weights.empty() ? 1.0f : o.weights[k];
                        const double r = w == 0.0f ? 0.0 : std::max(0.0, double(o.reference[k]));
                        sum += double(w) * r;
                        const int a = p - impl.a0(), b = c - impl.b0();
                        if (a >= 0 && a < impl.ma() && b >= 0 && b < impl.mb()) {
                            s->sqrt_ref(a, b) = float(std::sqrt(r));
                            if (s->weight.size()) s->weight(a, b) = w;
                        } else {
                            s->outside += double(w) * r;
                        }
                    }
                totals[i] = sum;
                built[i] = std::move(s);
            });
        guard.rethrow();
    }
    std::vector<RetrievalSlice> slices;
    slices.reserve(observations.size());
    for (std::size_t i = 0; i < observations.size(); ++i) {
        slices.push_back(std::move(*built[i]));
        built[i].reset();
    }
    total = detail::exact_total(totals, comm);  // every rank's, in any order
    if (!(total > 0.0)) throw std::invalid_argument("retrieve_field: every reference slice is zero");
    return slices;
}

// 1 on the fine-grid samples some footprint (of any rank) sees, 0 on the others: texels no
// footprint sees carry no information and stay 0.
std::vector<double> coverage_mask(const std::vector<RetrievalSlice>& slices, std::size_t texels,
                                  const Communicator& comm) {
    std::vector<double> mask(texels);
    std::vector<double> coverage(texels, 0.0);  // released on return: the grid is ~80 samples per texel
    {
        detail::ExactVector exact_coverage(texels);  // every rank's footprints, exactly
        for (const RetrievalSlice& s : slices)
            FieldAccess::impl(s.op).add_coverage(
                [&](std::size_t sample, double value) { exact_coverage.add(sample, value); });
        exact_coverage.allreduce(comm);
        exact_coverage.values(coverage.data());
    }
    const double max_coverage = *std::max_element(coverage.begin(), coverage.end());
    for (std::size_t t = 0; t < texels; ++t) mask[t] = coverage[t] > 1e-12 * max_coverage ? 1.0 : 0.0;
    return mask;
}

// Unknowns: the object's spectrum inside the band the slices see (unitary DFT of the
// periodic object grid), or the object itself when band_limit is off. Frequencies outside
// every slice's disk (|u − ω_i/λ| ≤ 1/λ, widened by the window's spectral reach 3/(2πσ_p))
// reach no pixel and would only drift; leaving them out also makes fewer unknowns.
std::vector<std::size_t> band_indices(const std::vector<const Observation*>& observations, double lambda_um, int rows,
                                      int cols, double texel_um, int obj_rows, int obj_cols,
                                      const Communicator& comm) {
    std::vector<std::size_t> band;
    const double period_x = rows * texel_um, period_y = cols * texel_um;
    // The distinct disks (centre ω_i/λ, reach): observations of one acquisition share one
    // ω_i and σ_p, and testing each of the ~700 slices' copies of it at each of the ~3e5
    // frequencies took ~0.5 s per wavelength.
    std::vector<std::array<double, 3>> disks;
    for (const Observation* p : observations) {
        const Observation& o = *p;
        const double reach = 1.0 / lambda_um + 3.0 / (2.0 * k_pi * o.query.sigma_p_um);
        const std::array<double, 3> d{{o.query.omega_i[0] / lambda_um, o.query.omega_i[1] / lambda_um, reach}};
        if (std::find(disks.begin(), disks.end(), d) == disks.end()) disks.push_back(d);
    }
    if (comm.size() > 1) {  // the union of every rank's disks, in rank order
        std::vector<double> mine;
        for (const auto& d : disks) mine.insert(mine.end(), d.begin(), d.end());
        const std::vector<double> all = all_gather(comm, mine);
        disks.clear();
        for (std::size_t k = 0; k + 2 < all.size(); k += 3) {
            const std::array<double, 3> d{{all[k], all[k + 1], all[k + 2]}};
            if (std::find(disks.begin(), disks.end(), d) == disks.end()) disks.push_back(d);
        }
    }
    for (int a = 0; a < obj_rows; ++a)
        for (int b = 0; b < obj_cols; ++b) {
            const double nu_x = double(a < (obj_rows + 1) / 2 ? a : a - obj_rows) / period_x;
            const double nu_y = double(b < (obj_cols + 1) / 2 ? b : b - obj_cols) / period_y;
            bool inside = false;
            for (const auto& [cx, cy, reach] : disks) {
                if ((nu_x - cx) * (nu_x - cx) + (nu_y - cy) * (nu_y - cy) <= reach * reach) {
                    inside = true;
                    break;
                }
            }
            if (inside) band.push_back(std::size_t(a) * obj_cols + b);
        }
    return band;  // indices of the spectrum kept, row-major
}

}  // namespace

FieldRetrievalResult retrieve_field(const std::vector<const Observation*>& observations, double lambda_um, int rows,
                                    int cols, double texel_um, const std::vector<std::complex<double>>& initial,
                                    const FieldRetrievalSettings& settings,
                                    const std::function<bool(int, double)>& on_iteration, const Communicator& comm) {
    check_retrieval(observations, lambda_um, rows, cols, initial, settings, comm);
    // The object lives on the grid `refine` times finer than the texels.
    const int q = settings.refine;
    const std::size_t texels = std::size_t(rows) * q * std::size_t(std::max(cols, 0)) * q;
    const int obj_cols = cols * q;
    // One flat fine grid for all the operators, released when the retrieval ends.
    std::shared_ptr<const Heightfield> flat_grid;
    if (rows >= 1 && cols >= 1 && std::isfinite(texel_um) && texel_um > 0.0)
        flat_grid = shared_flat_grid(rows * q, cols * q, texel_um / q);
    double total = 0.0;
    const std::vector<RetrievalSlice> slices =
        build_retrieval_slices(observations, lambda_um, rows, cols, texel_um, q, comm, total);
    const std::vector<double> mask = coverage_mask(slices, texels, comm);
    std::vector<std::complex<double>> object(texels);
    for (std::size_t t = 0; t < texels; ++t) object[t] = mask[t] * (initial.empty() ? 1.0 : initial[t]);

    // L(O) = Σ_slices [Σ_box (√c1|Ψ| − √R)² + Σ_outside R] / Σ R (each pixel × its weight
    // where the observation has weights: amplitude_loss.h). With g = ∂L/∂Re Ψ + i ∂L/∂Im Ψ
    // = 2(√c1|Ψ| − √R) √c1 Ψ/|Ψ| / ΣR, the gradient G = ∂L/∂Re O + i ∂L/∂Im O is Aᴴ g.
    const double inv_total = 1.0 / total;
    // Σ over the slices on all threads and ranks, exactly (core/exact_sum.h): each slice's
    // gradient is written into its thread's scratch and only its footprint's samples (the
    // operator's rows × columns, wrapping around the tile) are added to the exact sums, so the
    // result is the same for any thread count and any split over ranks. The scratches and the
    // sums are kept from call to call.
    detail::ExactParallelSum exact_sum(2 * texels);
    // Slice i's loss term; its gradient added into `gradient` (on its footprint's samples).
    const auto slice_loss = [&](std::size_t i, const std::complex<double>* obj, std::complex<double>* gradient) {
        thread_local Eigen::MatrixXcf psi, g;
        const RetrievalSlice& s = slices[i];
        const auto& impl = FieldAccess::impl(s.op);
        impl.forward_unphased(obj, psi);
        // Self-calibrated exposure when asked (amplitude_loss.h), the model amplitude scaled by √e.
        const double v = s.weight.size() == 0
                             ? detail::amplitude_box_loss(psi, impl.amp_box(), s.sqrt_ref, detail::UnitWeight{},
                                                          s.outside, settings.calibrate_exposure, inv_total, g)
                             : detail::amplitude_box_loss(psi, impl.amp_box(), s.sqrt_ref, s.weight, s.outside,
                                                          settings.calibrate_exposure, inv_total, g);
        impl.adjoint_unphased_add(g, gradient);
        return v * inv_total;
    };
    const auto loss = [&](const std::complex<double>* obj, std::vector<std::complex<double>>& grad) {
        grad.resize(texels);
        return exact_sum.run(slices.size(), comm, reinterpret_cast<double*>(grad.data()),
                             [&](std::size_t i, detail::ExactScratch& scratch) {
                                 const double value = slice_loss(i, obj, scratch.complex_data());
                                 const auto& impl = FieldAccess::impl(slices[i].op);
                                 scratch.take_box(impl.row_index, impl.col_index, std::size_t(obj_cols), 2);
                                 return value;
                             });
    };

    // Unknowns: the object's spectrum inside the band the slices see (band_indices), or the object
    // itself when band_limit is off.
    const int obj_rows = rows * q;
    const std::vector<std::size_t> band = settings.band_limit ? band_indices(observations, lambda_um, rows, cols, texel_um,
                                                                             obj_rows, obj_cols, comm)
                                                              : std::vector<std::size_t>{};
    std::vector<std::complex<double>> spectrum(texels);
    std::unique_ptr<SplitFft2d> to_spectrum, to_object;
    if (settings.band_limit) {
        to_spectrum = std::make_unique<SplitFft2d>(obj_rows, obj_cols, spectrum.data(), FFTW_FORWARD);
        to_object = std::make_unique<SplitFft2d>(obj_rows, obj_cols, spectrum.data(), FFTW_BACKWARD);
    }
    const double unitary = 1.0 / std::sqrt(double(texels));
    const bool parallel_grid = detail::worth_parallel((long long)texels);
    // x (interleaved re/im of the kept spectrum) → object; object gradient → x gradient (the
    // adjoint of a unitary inverse DFT followed by a restriction is the DFT then the gather).
    // Every pass is elementwise and runs on all threads (serial, the clearing, scatter and
    // gather held the other core idle).
    const auto to_grid = [&](const std::vector<double>& x, std::vector<std::complex<double>>& obj) {
#pragma omp parallel for schedule(static) if (parallel_grid)
        for (std::size_t t = 0; t < texels; ++t) spectrum[t] = 0.0;
#pragma omp parallel for schedule(static) if (parallel_grid)
        for (std::size_t k = 0; k < band.size(); ++k) spectrum[band[k]] = {x[2 * k], x[2 * k + 1]};
        to_object->execute();
        obj.resize(texels);
#pragma omp parallel for schedule(static) if (parallel_grid)
        for (std::size_t t = 0; t < texels; ++t) obj[t] = unitary * mask[t] * spectrum[t];
    };
    const auto from_grid = [&](const std::vector<std::complex<double>>& g, std::vector<double>& x) {
#pragma omp parallel for schedule(static) if (parallel_grid)
        for (std::size_t t = 0; t < texels; ++t) spectrum[t] = unitary * mask[t] * g[t];
        to_spectrum->execute();
        x.resize(2 * band.size());
#pragma omp parallel for schedule(static) if (parallel_grid)
        for (std::size_t k = 0; k < band.size(); ++k) {
            x[2 * k] = spectrum[band[k]].real();
            x[2 * k + 1] = spectrum[band[k]].imag();
        }
    };

    FieldRetrievalResult result;
    std::vector<double> xv;
    if (settings.band_limit) {
        from_grid(object, xv);
    } else {
        xv.resize(2 * texels);
        for (std::size_t t = 0; t < texels; ++t) {
            xv[2 * t] = object[t].real();
            xv[2 * t + 1] = object[t].imag();
        }
    }
    std::vector<std::complex<double>>().swap(object);  // the start is in xv now
    std::vector<std::complex<double>> grad, trial;
    const auto objective = [&](const std::vector<double>& x, std::vector<double>& g) {
        double value;
        if (settings.band_limit) {
            to_grid(x, trial);
            value = loss(trial.data(), grad);
            from_grid(grad, g);
        } else {
            value = loss(reinterpret_cast<const std::complex<double>*>(x.data()), grad);
            g.resize(2 * texels);
            for (std::size_t t = 0; t < texels; ++t) {
                g[2 * t] = grad[t].real();
                g[2 * t + 1] = grad[t].imag();
            }
        }
        return value;  // loss: already every rank's sum
    };
    LbfgsOptions lo;
    lo.history = settings.history;
    lo.float_history = true;  // the pairs in float: half the field stage's largest allocation (docs/scale.md)
    lo.max_iterations = settings.iterations;
    lo.gradient_tolerance = 0.0;
    detail::StallRule stall(settings.stall_window, settings.stall_tolerance);
    const LbfgsResult r = lbfgs_minimize(objective, xv, lo, [&](int it, double value) {
        result.iterations = it;
        // Every rank stops at the same iteration (the rest of the rule is on replicated values).
        if (comm.any(on_iteration && !on_iteration(it, value))) return false;
        if (stall.stalled_at(value)) return false;
        return value > settings.relative_tolerance;
    });
    result.relative_loss = r.value;
    result.iterations = r.iterations;
    if (settings.band_limit) {
        to_grid(xv, result.object);
    } else {
        result.object.resize(texels);
        for (std::size_t t = 0; t < texels; ++t) result.object[t] = {xv[2 * t], xv[2 * t + 1]};
    }
    return result;
}

}  // namespace wavebrdf
