#include "slice_job.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "wavebrdf/io.h"
#include "wavebrdf/progress.h"

namespace wavebrdf::cli {

void run_slice_job(const Heightfield& heightfield, const Query& query, SliceJob job) {
    if (job.out_exr.empty() && job.png.empty())
        throw std::invalid_argument("no output given; expected --out F.exr and/or --png F.png");
    validate(query);
    validate_resolution(job.resolution);
    if (!job.out_exr.empty()) check_writable(job.out_exr);
    if (!job.png.empty()) check_writable(job.png);
    // write_rgb_png would reject it too, but only after the EXR is written: check up front.
    if (!job.png.empty() && !std::isfinite(job.exposure))
        throw std::domain_error("--exposure " + std::to_string(job.exposure) +
                                " is invalid; expected a finite number of stops");

    Progress progress("render", work_units(job.resolution) * static_cast<long long>(job.lambdas_um.size()), !job.quiet);
    job.options.progress = &progress;
    const auto start = std::chrono::steady_clock::now();
    RgbImage image;
    image.rows = image.cols = job.resolution;
    std::vector<double> full;  // the double-precision slice, kept for .npy output
    if (job.use_double) {
        full = render_rgb<double>(heightfield, query, job.lambdas_um, job.resolution, job.options);
        image.data.assign(full.begin(), full.end());
    } else {
        image.data = render_rgb<float>(heightfield, query, job.lambdas_um, job.resolution, job.options);
    }
    progress.finish();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    const auto ends_with = [](const std::string& s, const std::string& tail) {
        return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
    };
    if (!job.out_exr.empty() && ends_with(job.out_exr, ".npy")) {
        // NumPy output (n, n, 3) float64, for scripts that have no EXR reader.
        write_npy(job.out_exr, {std::size_t(image.rows), std::size_t(image.cols), 3},
                  job.use_double ? full : std::vector<double>(image.data.begin(), image.data.end()));
    } else if (!job.out_exr.empty()) {
        SliceAttributes attributes;
        attributes.query = query;
        attributes.lambdas_um = job.lambdas_um;
        attributes.resolution = job.resolution;
        attributes.channels = job.lambdas_um.size() == 1 ? 1 : 3;
        attributes.texel_um = heightfield.texel_um();
        attributes.vscale = heightfield.vscale();
        attributes.heightfield_rows = heightfield.rows();
        attributes.heightfield_cols = heightfield.cols();
        attributes.heightfield_file = job.heightfield_file;
        attributes.made_by = job.made_by;
        write_slice_exr(job.out_exr, image, attributes, job.with_alpha);
    }
    if (!job.png.empty()) write_rgb_png(job.png, image, job.exposure, job.tonemap);
    if (!job.quiet) {
        float peak = 0.0f;
        for (float v : image.data) peak = std::max(peak, v);
        std::fprintf(stderr, "rendered %dx%d slice, %zu wavelength%s, model %s, peak %.4g, %.3f s\n", job.resolution,
                     job.resolution, job.lambdas_um.size(), job.lambdas_um.size() == 1 ? "" : "s",
                     to_string(query.model), double(peak), seconds);
    }
}

}  // namespace wavebrdf::cli
