#pragma once
// Batches: many BRDF slices (and their height gradients) in one call, threaded ACROSS the batch.
//
// A batch is a list of items, each a query (footprint position, light, σ_p, model), a
// wavelength set ("band": one wavelength, or several mixed to RGB as render_rgb does) and the
// heightfield it reads. Every item renders exactly the slice render_rgb (channels 3) or
// render_slice (channels 1) gives for it; the items are spread over the OpenMP threads (each
// item on one thread, one parallel region for the whole batch, no fork/join per matrix product:
// inside a batch region the library's own loops run serially, core/parallel.h), and each thread
// reuses its slice plan (slice_plan.h) while consecutive items differ only in their heights.
// A batch with one item, or a run on one thread, renders as the single call does.
//
// Typical uses:
//   // one heightfield, one footprint, many lights (a tabulated BRDF)
//   SliceBatch b = batch_product(query, lights, {{query.x_um, query.y_um}}, {lambdas_um}, 64);
//   std::vector<float> slices = render_batch<float>(heightfield, b);   // lights.size() × 64² × 3
//   // B heightfields of one shape, the same query for each (Python's leading batch axes)
//   SliceBatch b = batch_per_heightfield(query, lambdas_um, 64, heightfields.size());
//
// Outputs are one contiguous buffer (items, n, n, channels): item b's pixel (i, j) channel c is
// out[((b · n + i) · n + j) · channels + c], each slice as render_rgb / render_slice lay it out.
// Results agree with a loop of single calls to about 1e-12 relative in double (equal where the
// single call also runs on one thread; a parallel reduction's order is the only difference).
#include <array>
#include <cstddef>
#include <vector>

#include "wavebrdf/brdf.h"
#include "wavebrdf/communicator.h"

namespace wavebrdf {

// One slice of a batch: `query` (its x_um, y_um, sigma_p_um, omega_i and model are used),
// the wavelength set bands[band] of its SliceBatch, and heightfields[heightfield] of the call.
struct BatchItem {
    Query query;
    std::size_t band = 0;
    std::size_t heightfield = 0;
};

// A batch of slice queries at one resolution and channel count.
struct SliceBatch {
    std::vector<BatchItem> items;
    // Wavelength sets, µm (each 1 … 256 wavelengths within 0.01 … 1000 µm); channels 1 needs
    // exactly one wavelength per set.
    std::vector<std::vector<double>> bands;
    int resolution = 64;  // slice size n, 1 … 8192
    int channels = 3;     // 3: RGB (render_rgb); 1: the one wavelength's slice (render_slice)
};

// The cartesian product lights × positions × bands for one heightfield (heightfield index 0):
// item (l, p, w) is at index (l · positions.size() + p) · bands.size() + w (bands fastest) and
// has base's σ_p and model, lights[l] as ω_i (projected, |ω_i| < 1) and positions[p] as
// (x_um, y_um). Empty lists give an empty batch. Nothing is validated here (render_batch
// validates).
SliceBatch batch_product(const Query& base, const std::vector<std::array<double, 2>>& lights,
                         const std::vector<std::array<double, 2>>& positions_um,
                         const std::vector<std::vector<double>>& bands, int resolution, int channels = 3);

// `heightfields` items, item b reading heightfield b with `query` and `lambdas_um` (one band).
SliceBatch batch_per_heightfield(const Query& query, const std::vector<double>& lambdas_um, int resolution,
                                 std::size_t heightfields, int channels = 3);

// Validates a batch for `heightfields` heightfields: resolution, channels, every band, every
// item's query (validate(Query)), band and heightfield indices in range, options (path, prune
// tolerance). Throws std::invalid_argument / std::domain_error naming the item and the value.
void validate(const SliceBatch& batch, std::size_t heightfields, const RenderOptions& options = {});

// Estimated peak memory (bytes) of render_batch (`gradients` false) or batch_gradient (true)
// in float (`float_bytes` 4) or double (8) on `threads` threads: the output (items · n² ·
// channels values), one plan per thread (estimate_render_bytes of the largest footprint), and
// for the gradient the weights and threads · heightfields gradient buffers. Computed in
// double, so hostile sizes give a huge number rather than an overflow.
double estimate_batch_bytes(const Heightfield& geometry, const SliceBatch& batch, std::size_t heightfields,
                            const RenderOptions& options, std::size_t float_bytes, bool gradients, int threads);

// Renders every item of `batch`: items · n² · channels values (layout above), f_r in 1/sr.
// `heightfields`: at least one, all of one geometry (rows, cols, texel width, vertical scale;
// std::invalid_argument otherwise). Validates the batch (validate above) and refuses
// (OutOfMemory, before any allocation) what estimate_batch_bytes says does not fit
// options.max_memory_gb. An empty batch returns an empty vector. options.progress advances
// by work_units(n) per item and wavelength. Interruptible (interrupt.h) between items.
template <typename Float>
std::vector<Float> render_batch(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                                const RenderOptions& options = {});
// The same for one heightfield (every item's heightfield index must be 0).
template <typename Float>
std::vector<Float> render_batch(const Heightfield& heightfield, const SliceBatch& batch,
                                const RenderOptions& options = {});

// render_batch split over the ranks of `comm` (communicator.h, docs/scale.md): the items in
// contiguous blocks (share_of), each rank renders its block, and rank 0 gathers them (in rounds
// of at most about 2^24 values) into the whole output, equal bit for bit to render_batch's (an
// item's slice does not depend on the other items of its batch); the other ranks return an
// empty vector. Every rank checks the whole batch and its own block's memory; a failure on any
// rank (a bad item, OutOfMemory, an interrupt) is agreed: RankFailed on every rank
// (with one rank: render_batch's own exceptions). options.progress advances by this rank's
// block. Collective: every rank calls it with the same batch.
template <typename Float>
std::vector<Float> render_batch_over_ranks(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                                           const Communicator& comm, const RenderOptions& options = {});

// The batch's vector-Jacobian product: for weights W (items · n² · channels, the layout of
// render_batch's output; e.g. dL/dslices), adds ∂(Σ_b Σ_p W_b[p] · slice_b[p])/∂h_k into
// gradients[k] for every heightfield k (rows·cols each, texel units): the sum over the items
// that read heightfield k. So one heightfield gets the sum over the whole batch, a batch of
// heightfields one gradient each. `gradients` follows adjoint.h's rule per entry: an empty
// outer vector is sized to heightfields.size(); an empty entry is sized and zeroed; other
// sizes are refused (std::invalid_argument). When `slices` is not null it receives the
// forward's output (as render_batch). Validation and memory check as render_batch.
// Reproducible for a given thread count (per-thread partial gradients added in thread order).
template <typename Float>
void batch_gradient(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                    const std::vector<double>& weights, std::vector<std::vector<double>>& gradients,
                    const RenderOptions& options = {}, std::vector<Float>* slices = nullptr);
// The same for one heightfield: the gradient summed over the batch added into `gradient`.
template <typename Float>
void batch_gradient(const Heightfield& heightfield, const SliceBatch& batch, const std::vector<double>& weights,
                    std::vector<double>& gradient, const RenderOptions& options = {},
                    std::vector<Float>* slices = nullptr);

}  // namespace wavebrdf
