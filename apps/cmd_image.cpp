// wavebrdf image: a camera picture of a plate carrying the heightfield (image.h, docs/image.md).
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.h"
#include "commands.h"
#include "wavebrdf/image.h"
#include "wavebrdf/io.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/spectrum.h"
#include "wavebrdf/text.h"

namespace wavebrdf::cli {

namespace {

struct ImageArgs {
    std::string heightfield;
    double texel_um = 1.0, vscale = 1.0;
    bool given_texel = false, given_vscale = false;
    std::string plane_size = "512";
    double sphere_radius = 0.0, cylinder_radius = 0.0, cylinder_length = 0.0;
    bool given_sphere = false, given_cylinder = false;
    std::string camera = "0,0,1000", look_at = "0,0,0", up;
    std::string resolution = "256";
    std::vector<std::string> point_lights, directional_lights, disc_lights;
    int disc_order = 4;
    double power_w = 1.0, irradiance = 1.0, blackbody_k = 0.0;
    double lambda_um = 0.5;
    int spectral = 0;
    bool given_spectral = false;
    std::string model = "OHS";
    std::string precision = "double";
    std::string out, png;
    double exposure = 0.0;
    bool fixed_exposure = false;
    int frames = 1;
    std::string orbit = "light";
    double start_deg = 0.0, end_deg = 360.0;
    bool quiet = false;
    ImageOptions options;
};

// "X,Y,Z" (three finite numbers) for option `name`.
std::array<double, 3> parse_vec3(const std::string& text, const std::string& name) {
    std::array<double, 3> v{};
    std::size_t at = 0;
    for (int k = 0; k < 3; ++k) {
        const std::size_t end = text.find(',', at);
        if ((k < 2) != (end != std::string::npos)) break;
        const std::string part = text.substr(at, k < 2 ? end - at : std::string::npos);
        try {
            std::size_t used = 0;
            v[std::size_t(k)] = std::stod(part, &used);
            if (used != part.size() || !std::isfinite(v[std::size_t(k)])) throw std::invalid_argument(part);
        } catch (const std::exception&) {
            throw std::invalid_argument(name + " '" + text + "' is invalid; expected three finite numbers X,Y,Z");
        }
        if (k == 2) return v;
        at = end + 1;
    }
    throw std::invalid_argument(name + " '" + text + "' is invalid; expected three finite numbers X,Y,Z");
}

// "N" or "A,B": one or two positive numbers.
std::array<double, 2> parse_pair(const std::string& text, const std::string& name) {
    const std::size_t comma = text.find(',');
    const std::string a = text.substr(0, comma), b = comma == std::string::npos ? a : text.substr(comma + 1);
    std::array<double, 2> v{};
    try {
        std::size_t ua = 0, ub = 0;
        v[0] = std::stod(a, &ua);
        v[1] = std::stod(b, &ub);
        if (ua != a.size() || ub != b.size()) throw std::invalid_argument(text);
    } catch (const std::exception&) {
        throw std::invalid_argument(name + " '" + text + "' is invalid; expected N or A,B");
    }
    return v;
}

std::string numbered(const std::string& path, int frame) {
    const std::size_t dot = path.rfind('.');
    const std::size_t slash = path.rfind('/');
    char number[16];
    std::snprintf(number, sizeof number, "_%04d", frame);
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path + number;
    return path.substr(0, dot) + number + path.substr(dot);
}

void run(ImageArgs a) {
    ImageOptions& o = a.options;
    o.model = parse_model(a.model);
    if (a.precision != "double" && a.precision != "float")
        throw std::invalid_argument("--precision '" + a.precision + "' is unknown; expected double or float");
    o.single_precision = a.precision == "float";
    o.plane_size_um = parse_pair(a.plane_size, "--plane-size-um");
    if (a.given_sphere) {
        o.shape = SampleShape::Sphere;
        o.radius_um = a.sphere_radius;
    }
    if (a.given_cylinder) {
        o.shape = SampleShape::Cylinder;
        o.radius_um = a.cylinder_radius;
        o.length_um = a.cylinder_length;
    }
    o.camera.position = parse_vec3(a.camera, "--camera");
    o.camera.look_at = parse_vec3(a.look_at, "--look-at");
    if (!a.up.empty()) {
        o.camera.up = parse_vec3(a.up, "--up");
        if (o.camera.up == std::array<double, 3>{{0.0, 0.0, 0.0}})
            throw std::domain_error(
                "--up " + a.up +
                " is invalid; expected a nonzero direction (default: +z, or -x looking straight down)");
    }
    const std::array<double, 2> res = parse_pair(a.resolution, "--resolution");
    if (!(res[0] >= 1 && res[0] <= 8192 && res[1] >= 1 && res[1] <= 8192 && res[0] == std::floor(res[0]) &&
          res[1] == std::floor(res[1])))
        throw std::domain_error("--resolution '" + a.resolution + "' is invalid; expected N or ROWS,COLS, 1 to 8192");
    o.camera.rows = static_cast<int>(res[0]);
    o.camera.cols = static_cast<int>(res[1]);
    if (a.given_spectral) {
        if (a.spectral < 1 || a.spectral > k_max_spectral_samples)
            throw std::domain_error("--spectral " + std::to_string(a.spectral) + " is out of range; expected 1 to 256");
        o.lambdas_um = spectral_wavelengths_um(a.spectral);
    } else {
        validate_lambda(a.lambda_um);
        o.lambdas_um = {a.lambda_um};
    }
    ImageLight base;
    base.power_w = a.power_w;
    base.irradiance_w_m2 = a.irradiance;
    if (a.blackbody_k != 0.0) {
        base.spectrum = LightSpectrum::Blackbody;
        base.temperature_k = a.blackbody_k;
    }
    for (const std::string& p : a.point_lights) {
        ImageLight l = base;
        l.kind = LightKind::Point;
        l.vector = parse_vec3(p, "--point-light");
        o.lights.push_back(l);
    }
    for (const std::string& d : a.directional_lights) {
        ImageLight l = base;
        l.kind = LightKind::Directional;
        l.vector = parse_vec3(d, "--directional-light");
        o.lights.push_back(l);
    }
    for (const std::string& d : a.disc_lights) {
        // "X,Y,Z,R": the centre, then the radius after the last comma.
        const std::size_t comma = d.rfind(',');
        ImageLight l = base;
        l.kind = LightKind::Disc;
        const std::string bad = "--disc-light '" + d + "' is invalid; expected four finite numbers X,Y,Z,R";
        if (comma == std::string::npos) throw std::invalid_argument(bad);
        try {
            l.vector = parse_vec3(d.substr(0, comma), "--disc-light");
            std::size_t used = 0;
            const std::string radius = d.substr(comma + 1);
            l.radius_um = std::stod(radius, &used);
            if (used != radius.size()) throw std::invalid_argument(radius);
        } catch (const std::exception&) {
            throw std::invalid_argument(bad);
        }
        l.disc_order = a.disc_order;
        o.lights.push_back(l);
    }
    if (a.frames < 1 || a.frames > 10000)
        throw std::domain_error("--frames " + std::to_string(a.frames) + " is out of range; expected 1 to 10000");
    if (a.orbit != "light" && a.orbit != "camera")
        throw std::invalid_argument("--orbit '" + a.orbit + "' is unknown; expected light or camera");
    for (const auto& [name, angle] :
         {std::pair<const char*, double>{"--start-deg", a.start_deg}, {"--end-deg", a.end_deg}})
        if (!(std::isfinite(angle) && std::abs(angle) <= 1e6))
            throw std::domain_error(std::string(name) + " " + format_shortest(angle) +
                                    " is invalid; expected a finite angle within +-1e6 deg");
    if (!std::isfinite(a.exposure))
        throw std::domain_error("--exposure " + std::to_string(a.exposure) + " is not finite");
    if (a.out.empty() && a.png.empty())
        throw std::invalid_argument("no output; expected --out I.exr and/or --png I.png");
    check_distinct_files({{"--heightfield", a.heightfield}, {"--out", a.out}, {"--png", a.png}});
    check_output_format("--out", a.out, {".exr"});
    check_output_format("--png", a.png, {".png"});
    const HeightfieldScale scale = resolve_scale_with_warnings(a.heightfield, if_given(a.given_texel, a.texel_um),
                                                               if_given(a.given_vscale, a.vscale), "--texel-um",
                                                               "--vscale");
    const Heightfield hf = read_heightfield_exr(a.heightfield, scale.texel_um, scale.vscale);

    // Every frame's scene validated before the first is rendered.
    auto frame_options = [&](int k) {
        ImageOptions f = o;
        const double t = a.frames > 1 ? double(k) / double(a.frames - 1) : 0.0;
        const double angle = a.frames > 1 ? a.start_deg + (a.end_deg - a.start_deg) * t : 0.0;
        if (a.frames > 1 && a.orbit == "light")
            for (ImageLight& l : f.lights) l.vector = orbit_about_z(l.vector, angle);
        if (a.frames > 1 && a.orbit == "camera") f.camera.position = orbit_about_z(f.camera.position, angle);
        return f;
    };
    std::vector<PreparedImage> prepared;
    for (int k = 0; k < a.frames; ++k) prepared.push_back(prepare_image(hf, frame_options(k)));
    if (!a.quiet) std::fprintf(stderr, "%s\n", prepared[0].memory_note.c_str());
    for (int k = 0; k < a.frames; ++k) {
        const std::string out = a.out.empty() ? "" : (a.frames > 1 ? numbered(a.out, k) : a.out);
        const std::string png = a.png.empty() ? "" : (a.frames > 1 ? numbered(a.png, k) : a.png);
        if (!out.empty()) check_writable(out);
        if (!png.empty()) check_writable(png);
    }
    double exposure = a.exposure;
    for (int k = 0; k < a.frames; ++k) {
        Progress progress(a.frames > 1 ? "image " + std::to_string(k + 1) + "/" + std::to_string(a.frames) : "image",
                          o.camera.rows, !a.quiet);
        const RgbImage image = render_image(hf, prepared[std::size_t(k)], [&](int, int) {
            progress.advance(1);
            return true;
        });
        progress.finish();
        const std::string out = a.out.empty() ? "" : (a.frames > 1 ? numbered(a.out, k) : a.out);
        const std::string png = a.png.empty() ? "" : (a.frames > 1 ? numbered(a.png, k) : a.png);
        if (!out.empty()) write_image_exr(out, image, "wavebrdf image");
        if (!png.empty()) {
            // One exposure for the whole sequence (the first frame's), so glints keep their brightness.
            if (k == 0 && !a.fixed_exposure) exposure += auto_exposure(image_luminance(image));
            write_image_png(png, image, exposure, false);
        }
    }
}

}  // namespace

void add_image_command(CLI::App& app) {
    auto a = std::make_shared<ImageArgs>();
    CLI::App* cmd = app.add_subcommand("image",
                                       "Render a camera picture of a plate carrying the heightfield "
                                       "(docs/image.md)");
    cmd->footer(std::string("EXR unit: ") + k_image_unit +
                ". Positions in um; z is the plate's normal, x and y the heightfield's rows and columns, the "
                "plate centred at the origin.");
    cmd->add_option("--heightfield", a->heightfield, "heightfield EXR (R channel, heights in texel widths)")
        ->required();
    auto* texel = cmd->add_option("--texel-um", a->texel_um, "texel width w in um (default: the file's, else 1)");
    auto* vscale = cmd->add_option("--vscale", a->vscale, "vertical scale v (default: the file's, else 1)");
    auto* plane_size = cmd->add_option("--plane-size-um", a->plane_size,
                                       "plate size W or W,H in um (x by y), tiled with the heightfield")
                           ->capture_default_str();
    auto* sphere = cmd->add_option("--sphere-radius-um", a->sphere_radius,
                                   "sample: a sphere of this radius about the origin instead of the plate");
    auto* cylinder = cmd->add_option("--cylinder-radius-um", a->cylinder_radius,
                                     "sample: a cylinder of this radius about the x axis instead of the plate");
    auto* length = cmd->add_option("--cylinder-length-um", a->cylinder_length,
                                   "the cylinder's length along x, centred at the origin");
    sphere->excludes(cylinder);
    plane_size->excludes(sphere)->excludes(cylinder);
    cylinder->needs(length);
    length->needs(cylinder);
    cmd->add_option("--rotation-deg", a->options.rotation_deg, "heightfield rotation about the surface normal, degrees")
        ->capture_default_str();
    cmd->add_option("--camera", a->camera, "camera position X,Y,Z in um (z > 0)")->capture_default_str();
    cmd->add_option("--look-at", a->look_at, "point the camera looks at, X,Y,Z in um")->capture_default_str();
    cmd->add_option("--up", a->up, "up direction X,Y,Z (default +z, or -x looking straight down)");
    cmd->add_option("--fov-deg", a->options.camera.fov_deg, "pinhole field of view across the rows, degrees")
        ->capture_default_str();
    cmd->add_flag("--orthographic", a->options.camera.orthographic, "parallel projection along the view direction");
    cmd->add_option("--view-width-um", a->options.camera.view_width_um,
                    "orthographic: view width across the rows in um (0: the plate's width)")
        ->capture_default_str();
    cmd->add_option("--resolution", a->resolution, "image size N (N x N) or ROWS,COLS")->capture_default_str();
    cmd->add_option("--point-light", a->point_lights, "point light position X,Y,Z in um (repeatable)");
    cmd->add_option("--directional-light", a->directional_lights,
                    "directional light: direction X,Y,Z from the surface towards the light (repeatable)");
    cmd->add_option("--disc-light", a->disc_lights,
                    "disc area light X,Y,Z,R: centre in um facing the origin, radius in um (repeatable)");
    cmd->add_option("--disc-order", a->disc_order, "disc lights' quadrature: N Gauss-Legendre radii x 2N angles")
        ->capture_default_str();
    cmd->add_option("--power-w", a->power_w, "point and disc lights' radiant power, W")->capture_default_str();
    cmd->add_option("--irradiance", a->irradiance, "directional lights' irradiance, W/m^2")->capture_default_str();
    cmd->add_option("--blackbody-k", a->blackbody_k, "lights' spectrum: blackbody at T kelvin (default: white)");
    auto* lambda = cmd->add_option("--lambda-um", a->lambda_um, "single wavelength (laser) in um (default 0.5)");
    auto* spectral = cmd->add_option("--spectral", a->spectral,
                                     "K wavelengths over 0.36-0.83 um, CIE 1931 to linear sRGB");
    lambda->excludes(spectral);
    cmd->add_option("--model", a->model, "OHS, GHS, ROHS, RGHS or Kirchhoff")->capture_default_str();
    cmd->add_option("--sigma-p-um", a->options.sigma_p_um,
                    "footprint sigma_p in um for every pixel (0: from the pixel's projected size)")
        ->capture_default_str();
    cmd->add_option("--prune-tolerance", a->options.prune_tolerance,
                    "kernel pruning bound, relative to each pixel's largest possible value (0: full sum)")
        ->capture_default_str();
    cmd->add_option("--precision", a->precision, "the sum in double, or float (about 2x faster, ~1e-5 relative)")
        ->capture_default_str();
    cmd->add_option("--max-memory-gb", a->options.max_memory_gb,
                    "refuse a run whose estimated memory exceeds this many GB (0: the physical memory)")
        ->capture_default_str();
    cmd->add_option("--out", a->out, "output EXR (float RGB radiance, unit in its attributes)");
    cmd->add_option("--png", a->png, "tone-mapped 8-bit preview");
    cmd->add_option("--exposure", a->exposure,
                    "PNG exposure in stops, added to the automatic one (the first frame's 99.9th percentile of "
                    "the luminance to 4, then Reinhard)")
        ->capture_default_str();
    cmd->add_flag("--manual-exposure", a->fixed_exposure, "PNG: --exposure alone, no automatic part");
    cmd->add_option("--frames", a->frames, "frames of an orbit about the z axis (numbered outputs)")
        ->capture_default_str();
    cmd->add_option("--orbit", a->orbit, "what orbits with --frames: light or camera")->capture_default_str();
    cmd->add_option("--start-deg", a->start_deg, "orbit angle of the first frame, degrees")->capture_default_str();
    cmd->add_option("--end-deg", a->end_deg, "orbit angle of the last frame, degrees")->capture_default_str();
    cmd->add_flag("--quiet", a->quiet, "no progress bar or memory line");
    cmd->callback([a, spectral, texel, vscale, sphere, cylinder] {
        a->given_sphere = sphere->count() > 0;
        a->given_cylinder = cylinder->count() > 0;
        a->given_spectral = spectral->count() > 0;
        a->given_texel = texel->count() > 0;
        a->given_vscale = vscale->count() > 0;
        run(*a);
    });
}

}  // namespace wavebrdf::cli
