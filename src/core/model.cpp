#include "wavebrdf/model.h"

#include <cctype>
#include <cmath>
#include <stdexcept>

#include "core/text.h"

namespace wavebrdf {

namespace {
constexpr std::pair<Model, const char*> k_model_names[] = {{Model::OHS, "OHS"},
                                                           {Model::GHS, "GHS"},
                                                           {Model::ROHS, "ROHS"},
                                                           {Model::RGHS, "RGHS"},
                                                           {Model::Kirchhoff, "Kirchhoff"}};
}  // namespace

Model parse_model(const std::string& name) {
    Model model;
    if (detail::value_named(k_model_names, name, model)) return model;
    // Any case ("ohs", "kirchhoff"): the names differ in more than case.
    const auto lower = [](std::string s) {
        for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
        return s;
    };
    for (const auto& entry : k_model_names)
        if (lower(entry.second) == lower(name)) return entry.first;
    throw std::invalid_argument("unknown diffraction model '" + name +
                                "'; expected one of OHS, GHS, ROHS, RGHS, Kirchhoff");
}

const char* to_string(Model model) {
    const char* name = detail::name_of(k_model_names, model);
    return name ? name : "?";
}

void validate(const Query& query) {
    if (!std::isfinite(query.x_um) || !std::isfinite(query.y_um))
        throw std::domain_error("query position (" + format_shortest(query.x_um) + ", " + format_shortest(query.y_um) +
                                ") um is not finite");
    if (!std::isfinite(query.sigma_p_um) || query.sigma_p_um <= 0.0)
        throw std::domain_error("sigma_p " + format_shortest(query.sigma_p_um) +
                                " um is invalid; expected a finite value > 0");
    if (query.sigma_p_um < k_min_sigma_p_um || query.sigma_p_um > k_max_sigma_p_um)
        throw std::domain_error("sigma_p " + format_shortest(query.sigma_p_um) + " um is out of range; expected " +
                                format_shortest(k_min_sigma_p_um) + " to " + format_shortest(k_max_sigma_p_um) + " um");
    const double wx = query.omega_i[0], wy = query.omega_i[1];
    if (!std::isfinite(wx) || !std::isfinite(wy) || wx * wx + wy * wy >= 1.0)
        throw std::domain_error("light direction (" + format_shortest(wx) + ", " + format_shortest(wy) +
                                ") is invalid; expected a projected direction with |omega_i| < 1");
}

void validate_lambda(double lambda_um) {
    if (!std::isfinite(lambda_um) || lambda_um <= 0.0)
        throw std::domain_error("wavelength " + format_shortest(lambda_um) +
                                " um is invalid; expected a finite value > 0");
    if (lambda_um < k_min_lambda_um || lambda_um > k_max_lambda_um)
        throw std::domain_error("wavelength " + format_shortest(lambda_um) + " um is out of range; expected " +
                                format_shortest(k_min_lambda_um) + " to " + format_shortest(k_max_lambda_um) + " um");
}

void validate_resolution(int resolution) {
    if (resolution < 1 || resolution > 8192)
        throw std::domain_error("resolution " + std::to_string(resolution) + " is out of range; expected 1 to 8192");
}

DirectionFactors direction_factors(Model model, const std::array<double, 2>& omega_i, double omega_o_x,
                                   double omega_o_y, double lambda_um) {
    DirectionFactors f{};
    f.cos_theta_i = std::sqrt(std::abs(1.0 - omega_i[0] * omega_i[0] - omega_i[1] * omega_i[1]));
    f.cos_theta_o = std::sqrt(std::abs(1.0 - omega_o_x * omega_o_x - omega_o_y * omega_o_y));
    const double ci = f.cos_theta_i, co = f.cos_theta_o, l2 = lambda_um * lambda_um;
    switch (model) {
        case Model::OHS:
        case Model::GHS: f.c1 = co / (l2 * ci); break;
        case Model::ROHS:
        case Model::RGHS: f.c1 = (ci + co) * (ci + co) / (4.0 * l2 * ci * co); break;
        case Model::Kirchhoff: f.c1 = 1.0 / (4.0 * l2 * ci * co); break;
    }
    // GHS-type models scale the kernels' phase and frequency by C3/2, C3 = cos θ_i + cos θ_o.
    f.phase_scale = is_separable(model) ? 1.0 : 0.5 * (ci + co);
    return f;
}

}  // namespace wavebrdf
