#pragma once
// Observations: reference BRDF slices with the queries that produced them, and the loss of a
// heightfield against a set of them, with its gradient (summed over wavelengths, positions,
// light directions; spectral slices through the CIE → sRGB weights).
#include <string>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/loss.h"

namespace wavebrdf {

struct Observation {
    Query query;
    std::vector<double> lambdas_um;  // one: single wavelength (1 channel); several: RGB (3)
    int resolution = 32;
    std::vector<double> reference;   // resolution² · channels(), row-major, interleaved
    int channels() const { return lambdas_um.size() == 1 ? 1 : 3; }
};

// Throws std::invalid_argument / std::domain_error naming the observation (by index) and the
// field: invalid query, wavelength or resolution; reference of the wrong size; non-finite
// reference values. Negative values are accepted (linear sRGB of an out-of-gamut spectral
// colour is negative); the losses clamp them to 0.
void validate(const Observation& observation, std::size_t index = 0);

// What `observation` would see of `heightfield`: resolution² · channels() values (double).
std::vector<double> render_observation(const Heightfield& heightfield, const Observation& observation,
                                       const RenderOptions& options = {});

// The mean over observations of loss(render(heightfield), reference) and, when `gradient` is
// not null, its gradient with respect to the raw heights (rows·cols, texel units; overwritten).
// `rendered`, when not null, receives each observation's rendered slice.
double observation_loss(const Heightfield& heightfield, const std::vector<Observation>& observations,
                        const Loss& loss, std::vector<double>* gradient,
                        const RenderOptions& options = {},
                        std::vector<std::vector<double>>* rendered = nullptr);

// Observations as JSON (so measured or rendered slices can be given to `invert`):
// {"observations": [{"x_um":…, "y_um":…, "sigma_p_um":…, "light": [wx, wy], "model": "OHS",
//   "lambda_um": 0.5 | "spectral": 8 | "lambdas_um": […], "resolution": 32,
//   "reference": "slice.exr" | [values…]}]}. A reference file is an EXR read with
// read_rgb_exr (its R channel for one wavelength, RGB for several), relative to the JSON's
// directory. Throws std::runtime_error naming the file and the field on any problem.
// Before any reference image is read, the references' memory (resolution² · channels doubles
// each, and an EXR reference's float image while it is read) is estimated from the JSON and
// refused (OutOfMemory, memory.h) above `max_memory_gb` GB (0: the physical memory).
std::vector<Observation> read_observations_json(const std::string& path, double max_memory_gb = 0.0);

// Where write_observations_json puts the references.
enum class ReferenceStorage {
    Inline,  // "reference": [values…] in the JSON: exact (every double round-trips)
    Exr,     // "reference": "NAME/slice_0000.exr" …, float EXR files in the folder NAME beside the
             // JSON (NAME: the JSON's file name without its extension): float precision
};

// Writes `observations` in the schema read_observations_json reads (one wavelength as
// "lambda_um", several as "lambdas_um"), atomically (each EXR reference too; the JSON last, so
// it never names a file not yet written). With ReferenceStorage::Exr the folder is created
// when missing. Throws std::runtime_error naming the file that cannot be written, and
// std::invalid_argument for ReferenceStorage::Exr when `path` has no file name to name the
// folder after.
void write_observations_json(const std::string& path, const std::vector<Observation>& observations,
                             ReferenceStorage references = ReferenceStorage::Inline);

}  // namespace wavebrdf
