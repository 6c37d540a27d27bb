#pragma once
// Observations: reference BRDF slices with the queries that produced them, and the loss of a
// heightfield against a set of them, with its gradient (summed over wavelengths, positions,
// light directions; spectral slices through the CIE → sRGB weights).
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "wavebrdf/io.h"
#include "wavebrdf/brdf.h"
#include "wavebrdf/communicator.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/slice_plan.h"

namespace wavebrdf {

struct Observation {
    Query query;
    std::vector<double> lambdas_um;  // one: single wavelength (1 channel); several: RGB (3)
    int resolution = 32;
    // resolution² · channels(), row-major, interleaved. Float: the slices are float on disk
    // (EXR), and half the memory of the recovery's largest input.
    std::vector<float> reference;
    // One weight per pixel (resolution², row-major), or empty: every pixel weighs 1. The loss
    // is the weighted mean over pixels (weighted_loss_value, loss.h): a pixel of weight 0 (dead,
    // saturated, unmeasured) influences neither the loss nor its gradient, and its reference
    // may be any value, NaN included. Each finite and ≥ 0, at least one > 0.
    std::vector<float> weights;
    int channels() const { return lambdas_um.size() == 1 ? 1 : 3; }
};

// The attributes of a slice EXR of `observation` (io.h write_slice_exr): its query, wavelengths
// and resolution; the heightfield's scale and size when `heightfield` is not null.
SliceAttributes slice_attributes(const Observation& observation, const Heightfield* heightfield,
                                 const std::string& made_by);

// Throws std::invalid_argument / std::domain_error naming the observation (by index) and the
// field: invalid query, wavelength or resolution; reference of the wrong size; non-finite
// reference values (at pixels of weight > 0); weights of the wrong count, negative or
// non-finite, or all 0. Negative values are accepted (linear sRGB of an out-of-gamut spectral
// colour is negative); the losses clamp them to 0.
void validate(const Observation& observation, std::size_t index = 0);

// `values` rounded to float, as Observation::reference holds them.
std::vector<float> to_reference(const std::vector<double>& values);
// Observation::reference (or any float slice) as doubles, for the functions that take a double slice.
std::vector<double> to_doubles(const std::vector<float>& values);

// The footprint centre (query.x_um, query.y_um) of each observation, in order: the positions
// observation_share (communicator.h) splits.
std::vector<std::array<double, 2>> footprint_centres(const std::vector<Observation>& observations);

// What `observation` would see of `heightfield`: resolution² · channels() values (double).
std::vector<double> render_observation(const Heightfield& heightfield, const Observation& observation,
                                       const RenderOptions& options = {});

// A cache of slice plans (slice_plan.h) for observations, so that repeated losses of the same
// observations (an inversion's epochs) build each plan once. A plan is found again when the
// observation's query, wavelengths and resolution, the heightfield's geometry and the render
// path and prune tolerance are the same. It keeps at most `capacity` plans (observation_loss
// raises it to 2 · its observations + 2), dropping the least recently used. Not thread-safe:
// one cache per thread. Copying gives an empty cache (plans are rebuilt on use).
class ObservationPlans {
public:
    ObservationPlans() = default;
    ObservationPlans(const ObservationPlans&) {}
    ObservationPlans& operator=(const ObservationPlans&) {
        m_entries.clear();
        return *this;
    }
    ObservationPlans(ObservationPlans&&) noexcept = default;
    ObservationPlans& operator=(ObservationPlans&&) noexcept = default;

    // The plan for `observation` (double precision, differentiable) with `heightfield`'s
    // heights set; built when none matches. Arguments are validated as render_rgb does.
    SlicePlan<double>& plan(const Heightfield& heightfield, const Observation& observation,
                            const RenderOptions& options);
    // Keeps at least this many plans from now on.
    void reserve(std::size_t capacity);
    std::size_t size() const { return m_entries.size(); }
    // Plans built so far (for tests and benchmarks: a cache that works builds each once).
    std::size_t built() const { return m_built; }

private:
    struct Entry {
        std::unique_ptr<SlicePlan<double>> plan;
        unsigned long long last_use = 0;
    };
    std::vector<Entry> m_entries;
    std::size_t m_capacity = 2;
    unsigned long long m_clock = 0;
    std::size_t m_built = 0;
};

// The loss of one observation's rendered slice `estimate`: loss_value, or weighted_loss_value
// with the observation's weights when it has any.
double observation_slice_loss(const Loss& loss, const std::vector<double>& estimate, const Observation& observation,
                              std::vector<double>* gradient = nullptr);

// The mean over observations of loss(render(heightfield), reference) (each observation's
// pixels weighted by its weights when it has any) and, when `gradient` is
// not null, its gradient with respect to the raw heights (rows·cols, texel units), ADDED into
// `*gradient` (the convention of adjoint.h: pass an empty vector for the gradient alone).
// `rendered`, when not null, receives each observation's rendered slice. `plans`, when not
// null, keeps each observation's slice plan for the next call (an inversion passes the same
// cache every epoch); without it, each call builds and drops its plans.
// With a communicator of several ranks (communicator.h), `observations` are this rank's share
// (possibly none) and the loss and gradient are those of all ranks' observations together: the
// mean over their total count; `rendered` holds this rank's slices only. Collective: every rank
// calls it. The sums over observations are exact and order-independent (src/core/exact_sum.h),
// so the loss and gradient are the same bits on every rank, for any split over ranks and any
// thread count; each term (an observation's loss / count, a texel's gradient) must be below
// 2^32 in magnitude (std::overflow_error otherwise) and is resolved to 2^-72 absolute.
double observation_loss(const Heightfield& heightfield, const std::vector<Observation>& observations, const Loss& loss,
                        std::vector<double>* gradient, const RenderOptions& options = {},
                        std::vector<std::vector<double>>* rendered = nullptr, ObservationPlans* plans = nullptr,
                        const Communicator& comm = serial_communicator());

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
