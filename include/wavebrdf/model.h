#pragma once
// The diffraction models of docs/model.md §5 and the query (pixel footprint and light direction)
// that selects one BRDF slice of a heightfield.
#include <array>
#include <string>

namespace wavebrdf {

// OHS: original Harvey–Shack; GHS: generalised Harvey–Shack; R…: their reciprocal
// variants; Kirchhoff: Beckmann–Kirchhoff. Only OHS and ROHS are separable in u_x, u_y.
enum class Model { OHS, GHS, ROHS, RGHS, Kirchhoff };

// Parses the names above (exact spelling, as genBrdf's -d); throws std::invalid_argument
// naming the value and listing the accepted names otherwise.
Model parse_model(const std::string& name);
const char* to_string(Model model);
inline bool is_separable(Model model) { return model == Model::OHS || model == Model::ROHS; }

// One BRDF query: a Gaussian coherence window (pixel footprint) and a light direction.
struct Query {
    // Footprint centre μ_p along x (rows) and y (columns), µm: any finite value; it is reduced
    // modulo the tile period in floating point (footprint_kernels), so x and x + k · period
    // give the same slice for every integer k whose product is exact.
    double x_um = 0.0;
    double y_um = 0.0;
    // Footprint standard deviation σ_p, µm: k_min_sigma_p_um … k_max_sigma_p_um, and at most
    // k_max_sigma_p_periods tile periods (validate_footprint, gabor.h).
    double sigma_p_um = 10.0;
    // Projected direction towards the light, |ω_i| < 1 (cos θ_i = sqrt(1 − |ω_i|²)).
    std::array<double, 2> omega_i{{0.0, 0.0}};
    Model model = Model::OHS;
};

// Physically meaningful ranges, refused outside (values far outside them underflow or
// overflow to all-zero slices). Wavelength: extreme ultraviolet (13.5 nm lithography) to
// the far infrared / terahertz (1 mm). Footprint σ_p: a picometre to a metre (the planner's
// range, acquisition.h); the tile bounds it further (gabor.h).
constexpr double k_min_lambda_um = 0.01;
constexpr double k_max_lambda_um = 1000.0;
constexpr double k_min_sigma_p_um = 1e-6;
constexpr double k_max_sigma_p_um = 1e6;

// Throws std::domain_error naming the bad field: non-finite position, σ_p not finite or
// outside k_min_sigma_p_um … k_max_sigma_p_um, |ω_i| ≥ 1 or not finite.
void validate(const Query& query);
// Throws std::domain_error unless λ is finite and within k_min_lambda_um … k_max_lambda_um
// (0.01 … 1000 µm).
void validate_lambda(double lambda_um);
// Throws std::domain_error unless 1 ≤ resolution ≤ 8192.
void validate_resolution(int resolution);

// The projected outgoing direction of slice pixel (row i, column j) of an n × n slice:
// ω_o = ((i + ½)/n · 2 − 1, (j + ½)/n · 2 − 1). Pixels with |ω_o| > 1 are not rendered.
inline double slice_omega(int index, int resolution) { return (index + 0.5) / resolution * 2.0 - 1.0; }

// One slice pixel inside the unit disk: column q of its row and its ω_o = (ox, oy).
struct DiskPixel {
    int q;
    double ox, oy;
};

// The pixels of row p of an n × n slice with |ω_o|² ≤ 1 (the rendered ones), in column order:
//   for (const auto [q, ox, oy] : disk_row(p, n)) { … }
// The one copy of the loop "ω_o = (slice_omega(p, n), slice_omega(q, n)), skip outside the disk".
class DiskRow {
public:
    DiskRow(int p, int n) : m_ox(slice_omega(p, n)), m_n(n) {}

    class Iterator {
    public:
        Iterator(const DiskRow& row, int q) : m_row(&row), m_q(q) { skip_outside(); }
        DiskPixel operator*() const { return {m_q, m_row->m_ox, m_oy}; }
        Iterator& operator++() {
            ++m_q;
            skip_outside();
            return *this;
        }
        bool operator!=(const Iterator& other) const { return m_q != other.m_q; }

    private:
        void skip_outside() {
            for (; m_q < m_row->m_n; ++m_q) {
                m_oy = slice_omega(m_q, m_row->m_n);
                if (!(m_row->m_ox * m_row->m_ox + m_oy * m_oy > 1.0)) return;
            }
        }
        const DiskRow* m_row;
        int m_q;
        double m_oy = 0.0;
    };

    Iterator begin() const { return Iterator(*this, 0); }
    Iterator end() const { return Iterator(*this, m_n); }

private:
    double m_ox;
    int m_n;
};

inline DiskRow disk_row(int p, int n) { return DiskRow(p, n); }

// The per-direction factors of a model (docs/model.md §5). cos θ = sqrt(|1 − |ω|²|) as in
// the reference program.
struct DirectionFactors {
    double cos_theta_i;
    double cos_theta_o;
    double c1;           // f_r = c1 · |I|²  (includes 1/λ²)
    double phase_scale;  // C3/2: scales H − s·μ and s for GHS, RGHS, Kirchhoff; 1 otherwise
};
DirectionFactors direction_factors(Model model, const std::array<double, 2>& omega_i, double omega_o_x,
                                   double omega_o_y, double lambda_um);

}  // namespace wavebrdf
