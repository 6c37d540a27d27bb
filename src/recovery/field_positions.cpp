// Position correction inside the field stage (field_positions.h).

#include "recovery/field_positions.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>

#include <fftw3.h>

#include "core/exact_sum.h"
#include "core/fftw_planner.h"
#include "core/parallel.h"
#include "recovery/observation_loss.h"
#include "wavebrdf/constants.h"

namespace wavebrdf::detail {

double field_position_loss(const Observation& o, const std::array<double, 2>& offset_um,
                           const std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                           double texel_um, int refine, std::array<double, 2>* gradient_um) {
    Query q = o.query;
    q.x_um += offset_um[0];
    q.y_um += offset_um[1];
    const FieldOperator op(rows, cols, texel_um, q, lambda_um, o.resolution, refine);
    const std::vector<std::complex<double>> field = op.forward(object);
    const std::vector<double>& amp = op.amplitude_factor();
    if (o.reference.size() != field.size())
        throw std::invalid_argument("field_position_loss: reference has " + std::to_string(o.reference.size()) +
                                    " values; expected resolution^2 = " + std::to_string(field.size()));
    std::vector<std::complex<double>> g(gradient_um ? field.size() : 0);
    double sum = 0.0;
    for (std::size_t k = 0; k < field.size(); ++k) {
        const double w = value_weight(o, k);  // weight 0: not read
        if (amp[k] == 0.0 || w == 0.0) continue;
        // √w times the residual (√1 = 1: without weights the unweighted sums).
        const double root_w = std::sqrt(w), mag = std::abs(field[k]);
        const double d = root_w * (amp[k] * mag - std::sqrt(std::max(0.0, double(o.reference[k]))));
        sum += d * d;
        if (gradient_um && mag > 0.0) g[k] = (2.0 * root_w * d * amp[k] / mag) * field[k];
    }
    if (gradient_um) {
        // G = Aᴴ g, then Σ_a Re(conj(G_a) O_a) δ_a / σ_p² (field_positions.h), δ_a the sample's
        // periodic offset from the centre (the footprint's minimal image).
        const std::vector<std::complex<double>> grad = op.adjoint(g);
        const int nr = rows * refine, nc = cols * refine;
        const double d = texel_um / refine, period_x = rows * texel_um, period_y = cols * texel_um;
        const auto periodic = [](double v, double period) { return v - period * std::floor(v / period + 0.5); };
        double gx = 0.0, gy = 0.0;
        for (int a = 0; a < nr; ++a) {
            const double dx = periodic((a + 0.5) * d - q.x_um, period_x);
            for (int b = 0; b < nc; ++b) {
                const std::size_t s = std::size_t(a) * nc + b;
                if (grad[s] == 0.0) continue;
                const double w = grad[s].real() * object[s].real() + grad[s].imag() * object[s].imag();
                gx += w * dx;
                gy += w * periodic((b + 0.5) * d - q.y_um, period_y);
            }
        }
        const double inv_s2 = 1.0 / (q.sigma_p_um * q.sigma_p_um);
        *gradient_um = {gx * inv_s2, gy * inv_s2};
    }
    return sum;
}

std::vector<std::complex<double>> shift_object(const std::vector<std::complex<double>>& object, int rows, int cols,
                                               double texel_um, int refine, double shift_x_um, double shift_y_um) {
    const int nr = rows * refine, nc = cols * refine;
    if (rows < 1 || cols < 1 || refine < 1 || object.size() != std::size_t(nr) * std::size_t(nc))
        throw std::invalid_argument("shift_object: object has " + std::to_string(object.size()) +
                                    " values; expected (rows * refine) * (cols * refine)");
    std::vector<std::complex<double>> out(object);
    if (shift_x_um == 0.0 && shift_y_um == 0.0) return out;
    auto* data = reinterpret_cast<fftw_complex*>(out.data());
    fftw_plan forward, backward;
    {
        std::lock_guard<std::mutex> lock(fftw_planner_mutex());
        forward = fftw_plan_dft_2d(nr, nc, data, data, FFTW_FORWARD, FFTW_ESTIMATE);
        backward = fftw_plan_dft_2d(nr, nc, data, data, FFTW_BACKWARD, FFTW_ESTIMATE);
    }
    fftw_execute(forward);
    const double period_x = rows * texel_um, period_y = cols * texel_um, inv_n = 1.0 / (double(nr) * nc);
    for (int a = 0; a < nr; ++a) {
        // The Nyquist row/column (even sizes) is shifted as frequency 0: a band-limited object
        // has nothing there.
        const double nu_x = (2 * a == nr) ? 0.0 : double(a < (nr + 1) / 2 ? a : a - nr) / period_x;
        for (int b = 0; b < nc; ++b) {
            const double nu_y = (2 * b == nc) ? 0.0 : double(b < (nc + 1) / 2 ? b : b - nc) / period_y;
            out[std::size_t(a) * nc + b] *= inv_n *
                                            std::polar(1.0, -2.0 * k_pi * (nu_x * shift_x_um + nu_y * shift_y_um));
        }
    }
    fftw_execute(backward);
    {
        std::lock_guard<std::mutex> lock(fftw_planner_mutex());
        fftw_destroy_plan(forward);
        fftw_destroy_plan(backward);
    }
    return out;
}

namespace {

// Lockstep gradient steps on every position's offset (field_positions.h): eval(g, offset_um,
// gradient_um) is observation g's loss (already normalised) and its gradient at its position's
// trial offset. Every position's loss and gradient are summed exactly over every rank's
// observations. Returns the offsets (µm, 2 per position) after `steps` steps from x.
template <class Eval>
std::vector<double> descend_positions(std::size_t observations, const std::vector<std::size_t>& position,
                                      std::size_t count, double texel_um, int steps, std::vector<double> x,
                                      const Eval& eval, const Communicator& comm) {
    std::vector<double> loss(count), grad(2 * count), seen(count);
    const auto evaluate = [&](const std::vector<double>& trial, const std::vector<char>& active, std::vector<double>& l,
                              std::vector<double>& gr, std::vector<double>* n) {
        std::vector<double> values(3 * observations, 0.0);
        RegionGuard guard;
#pragma omp parallel for schedule(dynamic, 1) if (observations > 1 && !in_parallel_region())
        for (std::size_t g = 0; g < observations; ++g)
            guard.run([&] {
                const std::size_t p = position[g];
                if (!active[p]) return;
                std::array<double, 2> gp{0.0, 0.0};
                values[3 * g] = eval(g, std::array<double, 2>{trial[2 * p], trial[2 * p + 1]}, gp);
                values[3 * g + 1] = gp[0];
                values[3 * g + 2] = gp[1];
            });
        guard.rethrow();
        ExactVector sums(4 * count);
        for (std::size_t g = 0; g < observations; ++g) {
            const std::size_t p = position[g];
            if (!active[p]) continue;
            for (int c = 0; c < 3; ++c) sums.add(4 * p + std::size_t(c), values[3 * g + std::size_t(c)]);
            sums.add(4 * p + 3, 1.0);
        }
        sums.allreduce(comm);
        std::vector<double> all(4 * count);
        sums.values(all.data());
        for (std::size_t p = 0; p < count; ++p) {
            if (!active[p]) continue;
            l[p] = all[4 * p];
            gr[2 * p] = all[4 * p + 1];
            gr[2 * p + 1] = all[4 * p + 2];
            if (n) (*n)[p] = all[4 * p + 3];
        }
    };
    std::vector<char> active(count, 1);
    evaluate(x, active, loss, grad, &seen);
    for (std::size_t p = 0; p < count; ++p) active[p] = seen[p] > 0.0;
    // Step length per position (µm per unit gradient): the first step moves a quarter texel.
    std::vector<double> alpha(count, 0.0);
    for (std::size_t p = 0; p < count; ++p) {
        const double norm = std::hypot(grad[2 * p], grad[2 * p + 1]);
        if (!(norm > 0.0)) active[p] = 0;
        alpha[p] = active[p] ? 0.25 * texel_um / norm : 0.0;
    }
    std::vector<double> trial(x), trial_loss(count), trial_grad(2 * count), step(2 * count);
    for (int s = 0; s < steps; ++s) {
        std::vector<char> pending(active);
        for (std::size_t p = 0; p < count; ++p) {
            if (!pending[p]) continue;
            double sx = -alpha[p] * grad[2 * p], sy = -alpha[p] * grad[2 * p + 1];
            const double len = std::hypot(sx, sy);
            if (len > texel_um) {
                sx *= texel_um / len;
                sy *= texel_um / len;
            }
            step[2 * p] = sx;
            step[2 * p + 1] = sy;
        }
        for (int halving = 0; halving < 6; ++halving) {
            bool any = false;
            for (std::size_t p = 0; p < count; ++p)
                if (pending[p]) {
                    any = true;
                    trial[2 * p] = x[2 * p] + step[2 * p];
                    trial[2 * p + 1] = x[2 * p + 1] + step[2 * p + 1];
                }
            if (!any) break;
            evaluate(trial, pending, trial_loss, trial_grad, nullptr);
            for (std::size_t p = 0; p < count; ++p) {
                if (!pending[p]) continue;
                if (trial_loss[p] < loss[p]) {
                    // Barzilai–Borwein: s·s / s·y for the next step, when the curvature is positive.
                    const double sx = trial[2 * p] - x[2 * p], sy = trial[2 * p + 1] - x[2 * p + 1];
                    const double yx = trial_grad[2 * p] - grad[2 * p], yy = trial_grad[2 * p + 1] - grad[2 * p + 1];
                    const double sy_dot = sx * yx + sy * yy;
                    alpha[p] = sy_dot > 0.0 ? (sx * sx + sy * sy) / sy_dot : 2.0 * alpha[p];
                    x[2 * p] = trial[2 * p];
                    x[2 * p + 1] = trial[2 * p + 1];
                    loss[p] = trial_loss[p];
                    grad[2 * p] = trial_grad[2 * p];
                    grad[2 * p + 1] = trial_grad[2 * p + 1];
                    pending[p] = 0;
                } else {
                    step[2 * p] *= 0.5;
                    step[2 * p + 1] *= 0.5;
                    trial[2 * p] = x[2 * p];
                    trial[2 * p + 1] = x[2 * p + 1];
                }
            }
        }
        for (std::size_t p = 0; p < count; ++p)
            if (pending[p]) alpha[p] *= 1.0 / 64.0;
    }
    return x;
}

}  // namespace

namespace {

// correct_positions without the gauge: `steps` lockstep gradient steps at the fixed object on
// the offsets of the positions that `group` (every rank's) holds observations of; the others'
// offsets are left as they are. Returns false (nothing moved) when every rank's Σ R is 0.
// Collective.
bool register_positions(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                        const std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                        double texel_um, int refine, int steps, std::vector<double>& offsets_um,
                        const Communicator& comm) {
    if (position.size() != group.size())
        throw std::invalid_argument("correct_positions: " + std::to_string(position.size()) + " position indices for " +
                                    std::to_string(group.size()) + " observations; expected one each");
    const std::size_t count = offsets_um.size() / 2;
    for (std::size_t p : position)
        if (p >= count)
            throw std::invalid_argument("correct_positions: position index " + std::to_string(p) +
                                        " is out of range; expected < " + std::to_string(count));
    // The loss normalised by every rank's Σ w R (so every term is of order 1 or less).
    std::vector<double> totals(group.size(), 0.0);
    for (std::size_t g = 0; g < group.size(); ++g) totals[g] = weighted_reference_total(*group[g]);
    const double total = exact_total(totals, comm);
    if (!(total > 0.0)) return false;
    const double inv_total = 1.0 / total;

    std::vector<double> x = descend_positions(
        group.size(), position, count, texel_um, steps, offsets_um,
        [&](std::size_t g, const std::array<double, 2>& offset, std::array<double, 2>& gradient) {
            const double l = field_position_loss(*group[g], offset, object, lambda_um, rows, cols, texel_um, refine,
                                                 &gradient);
            gradient = {inv_total * gradient[0], inv_total * gradient[1]};
            return inv_total * l;
        },
        comm);
    offsets_um = std::move(x);
    return true;
}

// The gauge: every position moved by −m and every object by −m leave every slice as it was.
// Returns the rms (over positions and coordinates, texels) of the offsets' change from start.
double apply_gauge(std::vector<double>& x, const std::vector<double>& start,
                   const std::vector<std::vector<std::complex<double>>*>& objects, int rows, int cols, double texel_um,
                   int refine) {
    const std::size_t count = x.size() / 2;
    double mean[2] = {0.0, 0.0};
    for (std::size_t p = 0; p < count; ++p)
        for (int c = 0; c < 2; ++c) mean[c] += x[2 * p + std::size_t(c)] / double(count);
    for (std::size_t p = 0; p < count; ++p)
        for (int c = 0; c < 2; ++c) x[2 * p + std::size_t(c)] -= mean[c];
    for (std::vector<std::complex<double>>* object : objects)
        *object = shift_object(*object, rows, cols, texel_um, refine, -mean[0], -mean[1]);
    double moved = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) moved += (x[k] - start[k]) * (x[k] - start[k]);
    return count > 0 ? std::sqrt(moved / double(x.size())) / texel_um : 0.0;
}

}  // namespace

double correct_positions(const std::vector<const Observation*>& group, const std::vector<std::size_t>& position,
                         std::vector<std::complex<double>>& object, double lambda_um, int rows, int cols,
                         double texel_um, int refine, int steps, std::vector<double>& offsets_um,
                         const Communicator& comm) {
    const std::vector<double> start = offsets_um;
    if (!register_positions(group, position, object, lambda_um, rows, cols, texel_um, refine, steps, offsets_um, comm))
        return 0.0;
    return apply_gauge(offsets_um, start, {&object}, rows, cols, texel_um, refine);
}

FieldRetrievalResult retrieve_field_with_positions(
    const std::vector<const Observation*>& group, const std::vector<std::size_t>& position, double lambda_um, int rows,
    int cols, double texel_um, const std::vector<std::complex<double>>& initial, const FieldRetrievalSettings& settings,
    const std::function<bool(int, double)>& on_iteration, std::vector<double>& offsets_um, const Communicator& comm,
    int chunk_iterations, int steps) {
    if (chunk_iterations < 1 || steps < 0)
        throw std::invalid_argument("retrieve_field_with_positions: chunk " + std::to_string(chunk_iterations) +
                                    " / steps " + std::to_string(steps) + " invalid; expected >= 1 / >= 0");
    FieldRetrievalResult result;
    std::vector<std::complex<double>> object = initial;
    int done = 0;
    bool stopped = false;
    while (done < settings.iterations && !stopped) {
        FieldRetrievalSettings chunk = settings;
        chunk.iterations = std::min(chunk_iterations, settings.iterations - done);
        std::vector<Observation> shifted;
        shifted.reserve(group.size());
        for (std::size_t g = 0; g < group.size(); ++g) {
            shifted.push_back(*group[g]);
            shifted.back().query.x_um += offsets_um[2 * position[g]];
            shifted.back().query.y_um += offsets_um[2 * position[g] + 1];
        }
        const int before = done;
        FieldRetrievalResult r = retrieve_field(
            shifted, lambda_um, rows, cols, texel_um, object, chunk,
            [&](int it, double value) {
                const bool go_on = !on_iteration || on_iteration(before + it, value);
                if (!go_on) stopped = true;  // every rank stops at the same step (retrieve_field agrees)
                return go_on;
            },
            comm);
        std::vector<Observation>().swap(shifted);
        stopped = comm.any(stopped);  // one rank's stop (retrieve_field stopped every rank alike)
        done += std::max(1, r.iterations);
        result.relative_loss = r.relative_loss;
        object = std::move(r.object);
        if (stopped) break;
        const double moved = correct_positions(group, position, object, lambda_um, rows, cols, texel_um,
                                               settings.refine, steps, offsets_um, comm);
        if (r.iterations < chunk.iterations && moved < 0.01) break;  // the object stalled, the positions too
    }
    result.iterations = done;
    result.object = std::move(object);
    return result;
}

}  // namespace wavebrdf::detail
