// The brdf target (docs/design.md): a tabulated BRDF (table.h: a `wavebrdf table` or `wavebrdf
// lobe` file) matched by the tile's far field as a far observer sees it: the diffraction orders
// of each of the table's lights and wavelengths binned onto the table's ω_o pixels.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "design/target_more.h"
#include "wavebrdf/input_files.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/table.h"

namespace wavebrdf::detail {

namespace {

// The largest table a design reads: its mosaic (4096² pixels: 32 × 32 lights of 128² pixels, or
// 16 × 16 of 256²; 200 MB of float RGB) and the slice resolution (n² groups per order set).
constexpr long long k_max_brdf_mosaic_pixels = 4096LL * 4096LL;
constexpr int k_max_brdf_resolution = 256;

// The data window of an OpenEXR file from its raw header, without OpenEXR: the mosaic's size is
// bounded before read_brdf_table allocates its pixels. Returns false when the header cannot be
// walked to it (OpenEXR sorts the attributes by name, so dataWindow comes early).
bool exr_data_window(const std::string& path, long long& width, long long& height) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    std::string h(256 * 1024, '\0');
    in.read(h.data(), static_cast<std::streamsize>(h.size()));
    h.resize(static_cast<std::size_t>(in.gcount()));
    if (h.size() < 8 || static_cast<unsigned char>(h[0]) != 0x76 || static_cast<unsigned char>(h[1]) != 0x2f ||
        static_cast<unsigned char>(h[2]) != 0x31 || static_cast<unsigned char>(h[3]) != 0x01)
        return false;
    std::size_t at = 8;
    auto read_string = [&](std::string& s) {
        const std::size_t end = h.find('\0', at);
        if (end == std::string::npos || end - at > 255) return false;
        s = h.substr(at, end - at);
        at = end + 1;
        return true;
    };
    while (at < h.size()) {
        std::string name, type;
        if (!read_string(name)) return false;
        if (name.empty()) return false;  // the header's end without a data window
        if (!read_string(type) || at + 4 > h.size()) return false;
        std::uint32_t size = 0;
        for (int b = 3; b >= 0; --b) size = (size << 8) | static_cast<unsigned char>(h[at + static_cast<std::size_t>(b)]);
        at += 4;
        if (size > h.size() - at) return false;
        if (name == "dataWindow" && type == "box2i" && size == 16) {
            std::int32_t box[4];
            for (int k = 0; k < 4; ++k) {
                std::uint32_t v = 0;
                for (int b = 3; b >= 0; --b)
                    v = (v << 8) | static_cast<unsigned char>(h[at + static_cast<std::size_t>(4 * k + b)]);
                std::memcpy(&box[k], &v, 4);
            }
            width = static_cast<long long>(box[2]) - box[0] + 1;
            height = static_cast<long long>(box[3]) - box[1] + 1;
            return true;
        }
        at += size;
    }
    return false;
}

class Brdf final : public Target {
public:
    explicit Brdf(const BrdfSpec& spec) : m_spec(spec) {
        m_mix = spectral_mix_weights(spec.lambdas_um);
        const double step = 2.0 / spec.resolution;
        m_pixel_area = step * step;
        m_target_norm2 = 0.0;
        for (const auto& v : spec.values)
            for (float x : v) m_target_norm2 += static_cast<double>(x) * static_cast<double>(x);
    }
    int groups() const override { return m_spec.resolution * m_spec.resolution; }

    void assign(const std::vector<OrderSet>& sets) override {
        const std::size_t W = m_spec.lambdas_um.size();
        const int n = m_spec.resolution;
        m_members.assign(sets.size(), {});
        for (std::size_t s = 0; s < sets.size(); ++s) {
            const auto& light = m_spec.lights[s / W];
            const OrderSet& set = sets[s];
            m_members[s].assign(set.size(), {{-1, -1}});
            for (std::size_t o = 0; o < set.size(); ++o) {
                const double wx = -light[0] + set.dx(o), wy = -light[1] + set.dy(o);
                const int p = std::clamp(static_cast<int>(std::floor((wx + 1.0) / 2.0 * n)), 0, n - 1);
                const int q = std::clamp(static_cast<int>(std::floor((wy + 1.0) / 2.0 * n)), 0, n - 1);
                m_members[s][o][0] = p * n + q;
            }
        }
    }

    // The averaged BRDF of light l, pixel q, channel c: Σ_w M[c, w] f[l·W + w][q] / pixel area.
    double value(const Fractions& f, std::size_t l, std::size_t q, std::size_t c) const {
        const std::size_t W = m_spec.lambdas_um.size();
        double v = 0.0;
        for (std::size_t w = 0; w < W; ++w) v += m_mix[c * W + w] * f[l * W + w][q];
        return v / m_pixel_area;
    }

    // Squared relative L2 over every light, pixel and channel: Σ (f − t)² / Σ t².
    double loss(const Fractions& f, Fractions* gradient) const override {
        const std::size_t W = m_spec.lambdas_um.size(), P = static_cast<std::size_t>(groups());
        if (gradient) gradient->assign(f.size(), std::vector<double>(P, 0.0));
        const double inv = 1.0 / std::max(m_target_norm2, 1e-300);
        double total = 0.0;
        for (std::size_t l = 0; l < m_spec.lights.size(); ++l)
            for (std::size_t q = 0; q < P; ++q)
                for (std::size_t c = 0; c < 3; ++c) {
                    const double d = value(f, l, q, c) - static_cast<double>(m_spec.values[l][q * 3 + c]);
                    total += d * d * inv;
                    if (!gradient) continue;
                    const double g = 2.0 * d * inv / m_pixel_area;
                    for (std::size_t w = 0; w < W; ++w) (*gradient)[l * W + w][q] += g * m_mix[c * W + w];
                }
        return total;
    }

    nlohmann::json metrics(const Fractions& f) const override {
        const std::size_t P = static_cast<std::size_t>(groups());
        std::vector<double> per_light, albedo, target_albedo;
        double num = 0.0;
        for (std::size_t l = 0; l < m_spec.lights.size(); ++l) {
            double d2 = 0.0, t2 = 0.0, a = 0.0, ta = 0.0;
            for (std::size_t q = 0; q < P; ++q)
                for (std::size_t c = 0; c < 3; ++c) {
                    const double v = value(f, l, q, c), t = static_cast<double>(m_spec.values[l][q * 3 + c]);
                    d2 += (v - t) * (v - t);
                    t2 += t * t;
                    a += v * m_pixel_area / 3.0;
                    ta += t * m_pixel_area / 3.0;
                }
            num += d2;
            per_light.push_back(t2 > 0.0 ? std::sqrt(d2 / t2) : 0.0);
            albedo.push_back(a);
            target_albedo.push_back(ta);
        }
        return {{"relative_l2", m_target_norm2 > 0.0 ? std::sqrt(num / m_target_norm2) : 0.0},
                {"relative_l2_per_light", per_light},
                {"albedo", albedo},
                {"target_albedo", target_albedo}};
    }

private:
    BrdfSpec m_spec;
    std::vector<double> m_mix;
    double m_pixel_area = 1.0, m_target_norm2 = 0.0;
};

}  // namespace

DesignTarget read_brdf_target(const std::string& text, const std::string& path) {
    const std::string where = "--target '" + text + "'";
    if (path.empty()) throw std::invalid_argument(where + " names no file; expected brdf:TABLE.exr");
    try {
        check_readable_file(path);
    } catch (const std::runtime_error& e) {
        throw std::invalid_argument(where + ": " + e.what());
    }
    long long width = 0, height = 0;
    if (!exr_data_window(path, width, height))
        throw std::invalid_argument(path + ": no OpenEXR data window in the first 256 kB; expected a table file "
                                           "(docs/table.md)");
    if (width < 1 || height < 1 || width * height > k_max_brdf_mosaic_pixels)
        throw std::invalid_argument(path + ": a table mosaic of " + std::to_string(height) + " x " + std::to_string(width) +
                                    " pixels; a design reads at most 4096 x 4096 (fewer lights or a lower --resolution)");
    auto table = std::make_shared<BrdfTable>();
    try {
        *table = read_brdf_table(path);
    } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
    }
    if (table->spec.resolution > k_max_brdf_resolution)
        throw std::invalid_argument(path + ": table resolution " + std::to_string(table->spec.resolution) +
                                    "; a design bins onto at most " + std::to_string(k_max_brdf_resolution) +
                                    " pixels a side");
    if (std::count(table->rendered.begin(), table->rendered.end(), 1) == 0)
        throw std::invalid_argument(path + ": the table has no rendered light");
    DesignTarget t;
    t.kind = DesignKind::Brdf;
    t.text = text;
    t.table_file = path;
    t.table = std::move(table);
    return t;
}

std::unique_ptr<Target> make_brdf(const BrdfSpec& spec) { return std::make_unique<Brdf>(spec); }

}  // namespace wavebrdf::detail
