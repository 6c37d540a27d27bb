#include "wavebrdf/acquisition.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "core/random.h"
#include "core/text.h"
#include "wavebrdf/heightfield.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/progress.h"

namespace wavebrdf {

namespace {

using detail::format_shortest;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

void require_range(double value, double lo, double hi, const char* name) {
    if (!(std::isfinite(value) && value >= lo && value <= hi))
        throw std::domain_error(std::string(name) + " = " + format_shortest(value) + " is out of range; expected " +
                                format_shortest(lo) + " to " + format_shortest(hi));
}

// Window support D = 6σ_p (the model's 3σ_p cut on either side).
double support_um(double sigma_p_um) { return 6.0 * sigma_p_um; }

// Slice pixels n with Δu = 2/(nλ) ≤ 1/(2D), rounded up to a multiple of 8.
int nyquist_resolution(double sigma_p_um, double lambda_um) {
    const double n = 4.0 * support_um(sigma_p_um) / lambda_um;
    return static_cast<int>(std::ceil(n / 8.0 - 1e-9)) * 8;
}

// How much coarser than the Nyquist spacing 1/(2D) a slice may sample u: measured to work at
// 4.5×, to fail at 6× (docs/recovery.md); check_acquisition warns beyond it, the planner stays
// within it.
constexpr double k_max_nyquist_factor = 4.0;

// The smallest slice, a multiple of 8, whose Δu = 2/(nλ) is within k_max_nyquist_factor of
// 1/(2D): n ≥ D/λ.
int sampled_resolution(double sigma_p_um, double lambda_um) {
    const double n = 4.0 * support_um(sigma_p_um) / (k_max_nyquist_factor * lambda_um);
    return static_cast<int>(std::ceil(n / 8.0 - 1e-9)) * 8;
}

// The planner's slice size when none is given: the size the accuracy tables were measured at
// (docs/recovery.md, docs/surfaces.md: 48², a third of the default window's Nyquist size, the
// same accuracy at a tenth of the time), raised to what the window needs (sampled_resolution)
// where 48² samples it too coarsely (wide footprints: σ_p = 1.5 texels of 3.5 µm asks 64²).
// Not below 48² where Nyquist asks less (x3p-2's 0.5 µm texels: 40²): no smaller size was
// measured on the real scans.
constexpr int k_measured_slice_resolution = 48;
int planned_resolution(double sigma_p_um, double lambda_um) {
    return std::max(k_measured_slice_resolution, sampled_resolution(sigma_p_um, lambda_um));
}

// Periodic distance along one axis.
double wrapped(double d, double period) {
    d = std::fmod(std::abs(d), period);
    return std::min(d, period - d);
}

// Footprint centres bucketed on a periodic grid of cells at least `cell_um` wide, so that the
// centre nearest to a point is found by searching rings of cells outward from the point's cell
// instead of every centre: check_acquisition at 512² holds ~44 000 positions and 262 144
// texels, which the all-pairs search took tens of CPU minutes over.
class PeriodicCentreGrid {
public:
    PeriodicCentreGrid(const std::vector<std::array<double, 2>>& centres, double period_x_um, double period_y_um,
                       double cell_um)
        : m_centres(centres), m_period{{period_x_um, period_y_um}} {
        // At most ~2√P cells per axis (~4P in all) for P centres: a search never visits more cells
        // than there are centres to compare, whatever the periods and the cell width.
        const double max_cells = std::min(2048.0, std::ceil(2.0 * std::sqrt(double(m_centres.size()))) + 1.0);
        for (int a = 0; a < 2; ++a) {
            const double cells = std::floor(m_period[a] / cell_um);
            m_cells[a] = std::isfinite(cells) ? static_cast<int>(std::clamp(cells, 1.0, max_cells)) : 1;
            m_cell_um[a] = m_period[a] / m_cells[a];
        }
        m_start.assign(static_cast<std::size_t>(m_cells[0]) * m_cells[1] + 1, 0);
        std::vector<std::size_t> cell_of(m_centres.size());
        for (std::size_t c = 0; c < m_centres.size(); ++c) {
            cell_of[c] = cell_index(cell_coordinate(m_centres[c], 0), cell_coordinate(m_centres[c], 1));
            ++m_start[cell_of[c] + 1];
        }
        for (std::size_t k = 1; k < m_start.size(); ++k) m_start[k] += m_start[k - 1];
        m_members.resize(m_centres.size());
        std::vector<std::size_t> next(m_start.begin(), m_start.end() - 1);
        for (std::size_t c = 0; c < m_centres.size(); ++c) m_members[next[cell_of[c]]++] = c;
    }

    // The periodic distance (µm) from p to the nearest centre other than centres[skip] (pass
    // centres.size() to consider all); infinity when there is none.
    double nearest(const std::array<double, 2>& p, std::size_t skip) const {
        const int ci = cell_coordinate(p, 0), cj = cell_coordinate(p, 1);
        const double cell_min = std::min(m_cell_um[0], m_cell_um[1]);
        const int rings = std::max(m_cells[0], m_cells[1]);
        double best = std::numeric_limits<double>::infinity();
        const auto visit = [&](int di, int dj) {
            const std::size_t cell = cell_index(modulo(ci + di, m_cells[0]), modulo(cj + dj, m_cells[1]));
            for (std::size_t m = m_start[cell]; m < m_start[cell + 1]; ++m) {
                const std::size_t c = m_members[m];
                if (c == skip) continue;
                best = std::min(best, std::hypot(wrapped(p[0] - m_centres[c][0], m_period[0]),
                                                 wrapped(p[1] - m_centres[c][1], m_period[1])));
            }
        };
        for (int k = 0; k <= rings; ++k) {
            // Ring k: the cells at Chebyshev distance k (rows ±k whole, columns ±k without corners).
            if (k == 0) visit(0, 0);
            for (int d = -k; k > 0 && d <= k; ++d) {
                visit(-k, d);
                visit(k, d);
                if (d > -k && d < k) {
                    visit(d, -k);
                    visit(d, k);
                }
            }
            // A centre at distance d lies in a ring ≤ d / cell + 1: every centre closer than
            // (k − 1) cells has been seen.
            if (best <= (k - 1) * cell_min) break;
        }
        return best;
    }

private:
    static int modulo(int a, int n) { return ((a % n) + n) % n; }
    int cell_coordinate(const std::array<double, 2>& p, int axis) const {
        double x = std::fmod(p[axis], m_period[axis]);
        if (!(x >= 0.0)) x = std::isfinite(x) ? x + m_period[axis] : 0.0;
        return std::min(static_cast<int>(x / m_cell_um[axis]), m_cells[axis] - 1);
    }
    std::size_t cell_index(int i, int j) const { return static_cast<std::size_t>(i) * m_cells[1] + j; }

    std::vector<std::array<double, 2>> m_centres;
    std::array<double, 2> m_period;
    std::array<int, 2> m_cells{{1, 1}};
    std::array<double, 2> m_cell_um{{1.0, 1.0}};
    std::vector<std::size_t> m_start;    // CSR: the centres of cell k are m_members[m_start[k] .. m_start[k+1])
    std::vector<std::size_t> m_members;  // centre indices, grouped by cell
};

}  // namespace

std::vector<double> plan_wavelengths(double range_um, double lambda0, double lambda_min, double lambda_max,
                                     double max_ratio, std::vector<double>* synthetic_out) {
    require_range(range_um, 0.0, 1e6, "height range (um)");
    require_range(lambda0, lambda_min, lambda_max, "base wavelength lambda0 (um)");
    require_range(max_ratio, 1.5, 100.0, "ladder step ratio");
    std::vector<double> partners, synthetic;
    // One wavelength determines heights modulo λ0/2; keep the range within half of that.
    if (range_um >= 0.25 * lambda0) {
        // Finest synthetic wavelength the range [λ_min, λ_max] offers: the partner farthest from λ0.
        const double shortest = std::min(
            lambda_min < lambda0 ? lambda0 * lambda_min / (lambda0 - lambda_min) : kInfinity,
            lambda_max > lambda0 ? lambda0 * lambda_max / (lambda_max - lambda0) : kInfinity);
        if (!(shortest <= max_ratio * lambda0))
            throw std::domain_error(
                "wavelengths " + format_shortest(lambda_min) + " to " + format_shortest(lambda_max) +
                " um cannot bridge synthetic wavelengths down to lambda0 = " + format_shortest(lambda0) +
                " um within a step ratio of " + format_shortest(max_ratio) + "; heights up to " +
                format_shortest(0.25 * lambda0) + " um peak-to-valley need one wavelength only");
        // Λ_1 = 4 × range: the range fills half of the coarsest ambiguity interval Λ/2.
        double level = std::max(4.0 * range_um, shortest);
        for (;;) {
            synthetic.push_back(level);
            if (level <= max_ratio * lambda0) break;
            level = std::max(level / max_ratio, shortest);
        }
        for (double big : synthetic) {
            // Partner on the short side if available, else on the long side.
            const double shorter = lambda0 * big / (big + lambda0);
            partners.push_back(shorter >= lambda_min ? shorter : lambda0 * big / (big - lambda0));
        }
    }
    if (synthetic_out) *synthetic_out = synthetic;
    return partners;
}

AcquisitionPlan plan_acquisition(const PlanRequest& r) {
    if (r.rows < 1 || r.cols < 1)
        throw std::invalid_argument("heightfield size " + std::to_string(r.rows) + "x" + std::to_string(r.cols) +
                                    " is invalid; expected at least 1x1");
    require_range(r.texel_um, 1e-6, 1e6, "texel_um");
    require_range(r.overlap, 0.6, 0.95, "overlap");
    require_range(r.jitter, 0.0, 0.3, "jitter");
    require_range(r.lambda_min_um, 0.01, 100.0, "lambda_min_um");
    require_range(r.lambda_max_um, r.lambda_min_um, 100.0, "lambda_max_um");
    if (!(r.sigma_p_um == 0.0)) require_range(r.sigma_p_um, 1e-6, 1e6, "sigma_p_um");
    require_range(r.position_uncertainty_um, 0.0, 1e6, "position_uncertainty_um");
    Query probe;
    probe.omega_i = r.omega_i;
    probe.model = r.model;
    validate(probe);

    AcquisitionPlan plan;
    plan.omega_i = r.omega_i;
    plan.model = r.model;
    const bool sized_for_positions =
        r.sigma_p_um == 0.0 && k_footprint_per_position_uncertainty * r.position_uncertainty_um > 1.5 * r.texel_um;
    plan.sigma_p_um = r.sigma_p_um > 0.0     ? r.sigma_p_um
                      : sized_for_positions ? k_footprint_per_position_uncertainty * r.position_uncertainty_um
                                            : 1.5 * r.texel_um;
    const double d_um = support_um(plan.sigma_p_um);

    // Wavelengths: given, or λ0 and the ladder's partners.
    if (!r.lambdas_um.empty()) {
        for (double l : r.lambdas_um) validate_lambda(l);
        plan.lambdas_um = r.lambdas_um;
        for (std::size_t a = 0; a < plan.lambdas_um.size(); ++a)
            for (std::size_t b = a + 1; b < plan.lambdas_um.size(); ++b)
                if (plan.lambdas_um[a] != plan.lambdas_um[b])
                    plan.synthetic_um.push_back(plan.lambdas_um[a] * plan.lambdas_um[b] /
                                                std::abs(plan.lambdas_um[a] - plan.lambdas_um[b]));
        std::sort(plan.synthetic_um.rbegin(), plan.synthetic_um.rend());
    } else {
        plan.lambdas_um.push_back(r.lambda_um);
        const std::vector<double> partners = plan_wavelengths(r.height_range_um, r.lambda_um, r.lambda_min_um,
                                                              r.lambda_max_um, r.max_step_ratio, &plan.synthetic_um);
        plan.lambdas_um.insert(plan.lambdas_um.end(), partners.begin(), partners.end());
    }

    // Positions: a raster whose worst-case (jittered) neighbour distance keeps the overlap.
    const double period_x = r.rows * r.texel_um, period_y = r.cols * r.texel_um;
    // Worst case of two neighbours along x: jittered apart by up to 2·jitter·step along x and
    // across it (y) as well, so step·√((1 + 2j)² + (2j)²) apart.
    const double spread = std::hypot(1.0 + 2.0 * r.jitter, 2.0 * r.jitter);
    const double max_step = (1.0 - r.overlap) * d_um / spread;
    const int nx = std::max(1, static_cast<int>(std::ceil(period_x / max_step - 1e-9)));
    const int ny = std::max(1, static_cast<int>(std::ceil(period_y / max_step - 1e-9)));
    plan.step_x_um = period_x / nx;
    plan.step_y_um = period_y / ny;
    std::mt19937_64 rng(detail::derive_seed(r.seed, 17));
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j) {
            const double jx = (2.0 * detail::uniform01(rng) - 1.0) * r.jitter * plan.step_x_um;
            const double jy = (2.0 * detail::uniform01(rng) - 1.0) * r.jitter * plan.step_y_um;
            plan.positions_um.push_back({(i + 0.5) * plan.step_x_um + jx, (j + 0.5) * plan.step_y_um + jy});
        }
    plan.overlap = 1.0 - std::max(plan.step_x_um, plan.step_y_um) * spread / d_um;

    // Resolution: sampling the window at the shortest wavelength within k_max_nyquist_factor
    // of Nyquist (planned_resolution), or the given one (check_acquisition warns if too coarse).
    const double lambda_short = *std::min_element(plan.lambdas_um.begin(), plan.lambdas_um.end());
    plan.resolution = r.resolution != 0 ? r.resolution : planned_resolution(plan.sigma_p_um, lambda_short);
    validate_resolution(plan.resolution);

    plan.notes.push_back("footprint sigma_p = " + format_shortest(plan.sigma_p_um) +
                         " um (window support D = " + format_shortest(d_um) + " um" +
                         (sized_for_positions ? "; sized for positions uncertain by " +
                                                    format_shortest(r.position_uncertainty_um) + " um rms"
                                              : std::string()) +
                         ")");
    plan.notes.push_back(std::to_string(plan.positions_um.size()) + " positions on a " + std::to_string(nx) + "x" +
                         std::to_string(ny) + " raster, steps " + format_fixed(plan.step_x_um, 2) + " x " +
                         format_fixed(plan.step_y_um, 2) + " um, jitter +-" + format_fixed(100.0 * r.jitter, 0) +
                         " % of a step: neighbours overlap by at least " + format_fixed(100.0 * plan.overlap, 0) + " %");
    const double du = 2.0 / (plan.resolution * lambda_short);
    const bool raised = r.resolution == 0 && plan.resolution > k_measured_slice_resolution;
    plan.notes.push_back(std::to_string(plan.resolution) + "x" + std::to_string(plan.resolution) +
                         " slices" + (r.resolution != 0 ? " (given)" : "") + ": du = " + format_fixed(du, 4) +
                         " 1/um at lambda = " + format_fixed(lambda_short, 4) + " um, " +
                         (du <= 0.5 / d_um ? "<= " : format_fixed(du * 2.0 * d_um, 2) + "x, coarser than ") + "1/(2D) = " +
                         format_fixed(0.5 / d_um, 4) +
                         (raised ? " (raised from " + std::to_string(k_measured_slice_resolution) + "x" +
                                       std::to_string(k_measured_slice_resolution) + " to sample the window within " +
                                       format_shortest(k_max_nyquist_factor) + "x of Nyquist)"
                                 : std::string()));
    std::string lambdas;
    for (double l : plan.lambdas_um) lambdas += (lambdas.empty() ? "" : ", ") + format_fixed(l, 4);
    std::string synthetic;
    for (double s : plan.synthetic_um) synthetic += (synthetic.empty() ? "" : ", ") + format_fixed(s, 3);
    plan.notes.push_back("wavelengths " + lambdas + " um" +
                         (synthetic.empty()
                              ? std::string(r.lambdas_um.empty() ? " (one suffices for the height range)" : "")
                              : " (synthetic " + synthetic + " um; heights unwrap up to " +
                                    format_fixed(0.5 * plan.synthetic_um.front(), 3) + " um)"));
    return plan;
}

std::vector<Observation> planned_observations(const AcquisitionPlan& plan) {
    std::vector<Observation> out;
    std::vector<std::array<double, 2>> lights{plan.omega_i};
    lights.insert(lights.end(), plan.oblique_omega_i.begin(), plan.oblique_omega_i.end());
    const auto add = [&](const std::array<double, 2>& p, const std::array<double, 2>& light,
                         std::vector<double> lambdas_um) {
        Observation o;
        o.query.x_um = p[0];
        o.query.y_um = p[1];
        o.query.sigma_p_um = plan.sigma_p_um;
        o.query.omega_i = light;
        o.query.model = plan.model;
        o.lambdas_um = std::move(lambdas_um);
        o.resolution = plan.resolution;
        out.push_back(std::move(o));
    };
    for (const auto& p : plan.positions_um)
        for (const auto& light : lights)
            if (!plan.white_lambdas_um.empty())
                add(p, light, plan.white_lambdas_um);
            else
                for (double lambda : plan.lambdas_um) add(p, light, {lambda});
    return out;
}

std::size_t observations_per_position(const AcquisitionPlan& plan) {
    const std::size_t lights = 1 + plan.oblique_omega_i.size();
    return lights * (plan.white_lambdas_um.empty() ? plan.lambdas_um.size() : 1);
}

namespace {

// Renders observations[k] (planned observation index_of(k)) with its noise, one observation per
// thread (each slice alone is too small to split: at 64² the 2028 slices of 48² ran on one core
// for 0.5 s). The noise is added to the double slice, then rounded; every slice's noise has its
// own seed (its planned index), so the result depends neither on the thread count nor on which
// observations are rendered together.
template <typename IndexOf>
void render_with_noise(const Heightfield& truth, std::vector<Observation>& observations, IndexOf index_of,
                       const Noise& noise, std::uint64_t seed, Progress* progress) {
    detail::RegionGuard guard;
#pragma omp parallel for schedule(dynamic) if (observations.size() > 1 && !detail::in_parallel_region())
    for (std::size_t k = 0; k < observations.size(); ++k)
        guard.run([&] {
            Observation& o = observations[k];
            o.reference = to_reference(
                add_noise(render_observation(truth, o), noise, detail::derive_seed(seed, 1 + index_of(k))));
            if (progress) progress->advance(1);
        });
    guard.rethrow();
}

}  // namespace

std::vector<Observation> simulate_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                               const Noise& noise, std::uint64_t seed, Progress* progress) {
    std::vector<Observation> observations = planned_observations(plan);
    render_with_noise(
        truth, observations, [](std::size_t k) { return k; }, noise, seed, progress);
    return observations;
}

std::vector<Observation> simulate_observations(const Heightfield& truth, const AcquisitionPlan& plan,
                                               const Noise& noise, std::uint64_t seed,
                                               const std::vector<std::size_t>& indices, Progress* progress) {
    const std::vector<Observation> planned = planned_observations(plan);
    std::vector<Observation> observations;
    observations.reserve(indices.size());
    for (std::size_t i : indices) {
        if (i >= planned.size())
            throw std::invalid_argument("simulate_observations: index " + std::to_string(i) +
                                        " is out of range; the plan has " + std::to_string(planned.size()) +
                                        " observations");
        observations.push_back(planned[i]);
    }
    render_with_noise(
        truth, observations, [&](std::size_t k) { return indices[k]; }, noise, seed, progress);
    return observations;
}

std::vector<std::string> check_acquisition(const std::vector<Observation>& observations, int rows, int cols,
                                           double texel_um, const Heightfield* truth) {
    std::vector<std::string> warnings;
    if (observations.empty()) return {"no observations"};
    const double period_x = rows * texel_um, period_y = cols * texel_um;

    // Footprints, per σ_p: overlap of neighbours and coverage of the tile.
    std::set<double> sigmas;
    for (const Observation& o : observations) sigmas.insert(o.query.sigma_p_um);
    for (double sigma_p : sigmas) {
        std::vector<std::array<double, 2>> centres;
        for (const Observation& o : observations)
            if (o.query.sigma_p_um == sigma_p) centres.push_back({{o.query.x_um, o.query.y_um}});
        std::sort(centres.begin(), centres.end());
        centres.erase(std::unique(centres.begin(), centres.end()), centres.end());
        const std::string which = sigmas.size() > 1 ? " (sigma_p = " + format_shortest(sigma_p) + " um)" : "";
        const double d_um = support_um(sigma_p);
        const PeriodicCentreGrid grid(centres, period_x, period_y, 2.0 * sigma_p);
        if (centres.size() < 2) {
            warnings.push_back("one footprint position" + which +
                               ": a single window cannot determine the heights; use overlapping positions");
        } else {
            double worst = 0.0;  // the largest nearest-neighbour distance
            for (std::size_t a = 0; a < centres.size(); ++a) worst = std::max(worst, grid.nearest(centres[a], a));
            const double overlap = 1.0 - worst / d_um;
            if (overlap < 0.6)
                warnings.push_back("neighbouring footprints" + which + " overlap by only " + format_fixed(100.0 * overlap, 0) +
                                   " % (centres up to " + format_fixed(worst, 2) + " um apart, window D = 6 sigma_p = " +
                                   format_fixed(d_um, 2) + " um); expected at least 60 %");
        }
        int uncovered = 0;
        for (int i = 0; i < rows; ++i)
            for (int j = 0; j < cols; ++j) {
                const std::array<double, 2> t{{(i + 0.5) * texel_um, (j + 0.5) * texel_um}};
                if (grid.nearest(t, centres.size()) > 2.0 * sigma_p) ++uncovered;
            }
        if (uncovered > 0)
            warnings.push_back(std::to_string(uncovered) + " of " + std::to_string(rows * cols) + " texels" + which +
                               " are farther than 2 sigma_p from every footprint centre: their heights are "
                               "barely measured");
    }

    // Sampling of each slice: measured to work down to 4.5× the Nyquist spacing 1/(2D), to fail
    // at 6× (docs/recovery.md); warn beyond 4×.
    std::set<std::string> seen;
    for (const Observation& o : observations) {
        const double d_um = support_um(o.query.sigma_p_um);
        for (double lambda : o.lambdas_um) {
            const double du = 2.0 / (o.resolution * lambda);
            if (du <= k_max_nyquist_factor * 0.5 / d_um) continue;
            const int needed = static_cast<int>(
                std::ceil(nyquist_resolution(o.query.sigma_p_um, lambda) / k_max_nyquist_factor));
            const std::string w = std::to_string(o.resolution) + "x" + std::to_string(o.resolution) +
                                  " slices at lambda = " + format_shortest(lambda) + " um sample u every " +
                                  format_fixed(du, 4) +
                                  " 1/um, more than 4x the Nyquist spacing 1/(2D) = " + format_fixed(0.5 / d_um, 4) +
                                  " for sigma_p = " + format_shortest(o.query.sigma_p_um) + " um; expected at least " +
                                  std::to_string(needed) + " pixels";
            if (seen.insert(w).second) warnings.push_back(w);
        }
    }

    // Enough numbers for the unknowns.
    double values = 0.0;
    std::map<int, int> inside_of;  // disk pixels per slice resolution, counted once per resolution
    for (const Observation& o : observations) {
        auto [at, added] = inside_of.try_emplace(o.resolution, 0);
        if (added)
            for (int p = 0; p < o.resolution; ++p)
                for ([[maybe_unused]] const DiskPixel pixel : disk_row(p, o.resolution)) ++at->second;
        values += double(at->second) * double(o.lambdas_um.size());
    }
    if (values < double(rows) * cols)
        warnings.push_back("the slices hold " + format_fixed(values, 0) + " values for " + std::to_string(rows * cols) +
                           " heights: too few to determine them");

    // Light must reach a slice: a facet of slope s reflects light ω_i towards ω_o ≈ −ω_i − 2s,
    // measured when some observation's light puts that inside the rim (0.9: the disk's edge
    // pixels hold a fraction of the lobe).
    if (truth) {
        std::vector<std::array<double, 2>> lights;
        for (const Observation& o : observations)
            if (std::find(lights.begin(), lights.end(), o.query.omega_i) == lights.end())
                lights.push_back(o.query.omega_i);
        double max_unseen_slope = 0.0;
        long long unseen = 0;
        for (int i = 0; i < truth->rows(); ++i)
            for (int j = 0; j < truth->cols(); ++j) {
                const auto s = truth->slope(i, j);
                const bool seen = std::any_of(lights.begin(), lights.end(), [&](const std::array<double, 2>& w) {
                    return std::hypot(w[0] + 2.0 * s[0], w[1] + 2.0 * s[1]) <= 0.9;
                });
                if (!seen) {
                    ++unseen;
                    max_unseen_slope = std::max(max_unseen_slope, std::hypot(s[0], s[1]));
                }
            }
        const bool one = lights.size() == 1;
        if (unseen > 0)
            warnings.push_back(std::to_string(unseen) + " of " + std::to_string(truth->rows() * truth->cols()) +
                               " texels (slopes up to " + format_fixed(max_unseen_slope, 3) + ") reflect " +
                               (one ? "the light" : "each of the " + std::to_string(lights.size()) + " lights") +
                               " beyond the slice's rim (|omega_o| > 0.9): part of the field is not measured (use " +
                               (one ? "oblique lights, " : "") + "larger texels or lower heights)");
    }
    return warnings;
}

}  // namespace wavebrdf
