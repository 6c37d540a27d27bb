// Batches of slices (batch.h): building and validating a batch, its memory bound, and the
// forward render spread over the threads item by item (forward/batch_run.h).
#include "wavebrdf/batch.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include "core/text.h"
#include "forward/batch_run.h"
#include "wavebrdf/input_digest.h"
#include "wavebrdf/memory.h"

namespace wavebrdf {

namespace {

constexpr std::size_t k_max_band_wavelengths = 256;

std::string item_name(std::size_t b) { return "batch item " + std::to_string(b); }

}  // namespace

SliceBatch batch_product(const Query& base, const std::vector<std::array<double, 2>>& lights,
                         const std::vector<std::array<double, 2>>& positions_um,
                         const std::vector<std::vector<double>>& bands, int resolution, int channels) {
    SliceBatch batch;
    batch.bands = bands;
    batch.resolution = resolution;
    batch.channels = channels;
    batch.items.reserve(lights.size() * positions_um.size() * bands.size());
    for (const auto& light : lights)
        for (const auto& position : positions_um)
            for (std::size_t w = 0; w < bands.size(); ++w) {
                BatchItem item;
                item.query = base;
                item.query.omega_i = light;
                item.query.x_um = position[0];
                item.query.y_um = position[1];
                item.band = w;
                batch.items.push_back(item);
            }
    return batch;
}

SliceBatch batch_per_heightfield(const Query& query, const std::vector<double>& lambdas_um, int resolution,
                                 std::size_t heightfields, int channels) {
    SliceBatch batch;
    batch.bands = {lambdas_um};
    batch.resolution = resolution;
    batch.channels = channels;
    batch.items.resize(heightfields);
    for (std::size_t b = 0; b < heightfields; ++b) {
        batch.items[b].query = query;
        batch.items[b].heightfield = b;
    }
    return batch;
}

void validate(const SliceBatch& batch, std::size_t heightfields, const RenderOptions& options) {
    validate_resolution(batch.resolution);
    if (batch.channels != 1 && batch.channels != 3)
        throw std::invalid_argument("batch channels " + std::to_string(batch.channels) +
                                    " is invalid; expected 1 or 3");
    for (std::size_t w = 0; w < batch.bands.size(); ++w) {
        const std::vector<double>& band = batch.bands[w];
        if (band.empty() || band.size() > k_max_band_wavelengths)
            throw std::invalid_argument("batch band " + std::to_string(w) + " has " + std::to_string(band.size()) +
                                        " wavelengths; expected 1 to 256");
        if (batch.channels == 1 && band.size() != 1)
            throw std::invalid_argument("batch band " + std::to_string(w) + " has " + std::to_string(band.size()) +
                                        " wavelengths; one output channel needs exactly one");
        for (double lambda : band) validate_lambda(lambda);
    }
    for (std::size_t b = 0; b < batch.items.size(); ++b) {
        const BatchItem& item = batch.items[b];
        if (item.band >= batch.bands.size())
            throw std::invalid_argument(item_name(b) + " has band " + std::to_string(item.band) +
                                        "; expected below the batch's " + std::to_string(batch.bands.size()) +
                                        " bands");
        if (item.heightfield >= heightfields)
            throw std::invalid_argument(item_name(b) + " reads heightfield " + std::to_string(item.heightfield) +
                                        "; expected below the " + std::to_string(heightfields) + " given");
        try {
            validate(item.query);
            validate(options, item.query.model);
        } catch (const std::domain_error& e) {
            throw std::domain_error(item_name(b) + ": " + e.what());
        } catch (const std::invalid_argument& e) {
            throw std::invalid_argument(item_name(b) + ": " + e.what());
        }
    }
}

double estimate_batch_bytes(const Heightfield& geometry, const SliceBatch& batch, std::size_t heightfields,
                            const RenderOptions& options, std::size_t float_bytes, bool gradients, int threads) {
    const double n = double(batch.resolution), values = double(batch.items.size()) * n * n * double(batch.channels);
    double bytes = values * double(float_bytes);  // the output
    // One plan per thread, for the item with the widest footprint; a differentiable plan keeps
    // every wavelength's field and slice.
    double plan = 0.0;
    for (const BatchItem& item : batch.items) {
        const double wavelengths = gradients && item.band < batch.bands.size() ? double(batch.bands[item.band].size())
                                                                               : 1.0;
        plan = std::max(plan, wavelengths * estimate_render_bytes(geometry, item.query, batch.resolution, options,
                                                                  float_bytes, batch.channels == 3));
    }
    bytes += double(threads) * plan;
    if (gradients) {
        const double cells = double(geometry.rows()) * double(geometry.cols());
        bytes += values * 8.0;                                                  // the weights
        bytes += (double(threads) + 1.0) * double(heightfields) * cells * 8.0;  // partial and total gradients
    }
    return bytes;
}

namespace detail {

int prepare_batch(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                  const RenderOptions& options, std::size_t float_bytes, bool gradients) {
    if (heightfields.empty()) throw std::invalid_argument("no heightfields given; expected at least one");
    const Heightfield& first = *heightfields.front();
    for (std::size_t k = 1; k < heightfields.size(); ++k) {
        const Heightfield& hf = *heightfields[k];
        if (hf.rows() != first.rows() || hf.cols() != first.cols() || hf.texel_um() != first.texel_um() ||
            hf.vscale() != first.vscale())
            throw std::invalid_argument(
                "heightfield " + std::to_string(k) + " is " + std::to_string(hf.rows()) + "x" +
                std::to_string(hf.cols()) + " (texel " + format_shortest(hf.texel_um()) + " um, vscale " +
                format_shortest(hf.vscale()) + "); expected the geometry of heightfield 0 (" +
                std::to_string(first.rows()) + "x" + std::to_string(first.cols()) + ", texel " +
                format_shortest(first.texel_um()) + " um, vscale " + format_shortest(first.vscale()) + ")");
    }
    validate(batch, heightfields.size(), options);
    const int threads = in_parallel_region() ? 1
                                             : static_cast<int>(std::min<std::size_t>(
                                                   static_cast<std::size_t>(std::max(1, omp_get_max_threads())),
                                                   std::max<std::size_t>(1, batch.items.size())));
    const MemoryLimit limit = memory_limit(options.max_memory_gb);
    const double needed = estimate_batch_bytes(first, batch, heightfields.size(), options, float_bytes, gradients,
                                               threads);
    if (needed > limit.bytes)
        require_memory(needed, limit,
                       std::string(gradients ? "batch gradient (" : "batch render (") +
                           std::to_string(batch.items.size()) + " slices of " + std::to_string(batch.resolution) + "x" +
                           std::to_string(batch.resolution) + "x" + std::to_string(batch.channels) + ", " +
                           (float_bytes == 4 ? "float" : "double") + ")");
    return threads;
}

template <typename Float>
std::vector<Float> render_batch(const std::vector<const Heightfield*>& heightfields, const SliceBatch& batch,
                                const RenderOptions& options) {
    const int threads = prepare_batch(heightfields, batch, options, sizeof(Float), false);
    const std::size_t values = static_cast<std::size_t>(batch.resolution) * static_cast<std::size_t>(batch.resolution) *
                               static_cast<std::size_t>(batch.channels);
    std::vector<Float> out = allocating("the batch's output",
                                        double(values) * double(batch.items.size()) * sizeof(Float),
                                        [&] { return std::vector<Float>(values * batch.items.size()); });
    std::vector<BatchPlan<Float>> plans;
    plans.reserve(static_cast<std::size_t>(threads));
    for (int t = 0; t < threads; ++t) plans.emplace_back(heightfields, batch, options, false);
    for_each_item(batch.items.size(), threads, [&](std::size_t b, int t) {
        const std::vector<Float>& slice = plans[static_cast<std::size_t>(t)].plan_for(batch.items[b]).forward();
        std::copy(slice.begin(), slice.end(), out.begin() + static_cast<std::ptrdiff_t>(b * values));
    });
    return out;
}

template std::vector<float> render_batch<float>(const std::vector<const Heightfield*>&, const SliceBatch&,
                                                const RenderOptions&);
template std::vector<double> render_batch<double>(const std::vector<const Heightfield*>&, const SliceBatch&,
                                                  const RenderOptions&);

}  // namespace detail

template <typename Float>
std::vector<Float> render_batch(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                                const RenderOptions& options) {
    return detail::render_batch<Float>(detail::addresses(heightfields), batch, options);
}

template <typename Float>
std::vector<Float> render_batch(const Heightfield& heightfield, const SliceBatch& batch, const RenderOptions& options) {
    return detail::render_batch<Float>({&heightfield}, batch, options);
}

template std::vector<float> render_batch<float>(const std::vector<Heightfield>&, const SliceBatch&,
                                                const RenderOptions&);
template std::vector<double> render_batch<double>(const std::vector<Heightfield>&, const SliceBatch&,
                                                  const RenderOptions&);
template std::vector<float> render_batch<float>(const Heightfield&, const SliceBatch&, const RenderOptions&);
template std::vector<double> render_batch<double>(const Heightfield&, const SliceBatch&, const RenderOptions&);

template <typename Float>
std::vector<Float> render_batch_over_ranks(const std::vector<Heightfield>& heightfields, const SliceBatch& batch,
                                           const Communicator& comm, const RenderOptions& options) {
    if (comm.size() == 1) return render_batch<Float>(heightfields, batch, options);
    const std::size_t count = batch.items.size(), ranks = static_cast<std::size_t>(comm.size());
    const Share mine = share_of(count, comm.rank(), comm.size());
    SliceBatch part = batch;
    part.items.assign(batch.items.begin() + std::ptrdiff_t(mine.begin), batch.items.begin() + std::ptrdiff_t(mine.end));
    const std::size_t values = static_cast<std::size_t>(batch.resolution) * static_cast<std::size_t>(batch.resolution) *
                               static_cast<std::size_t>(batch.channels);
    std::vector<Float> local, out;
    // Every rank must have been given the same batch: the shares and the gathers below assume
    // it (different counts abort in MPI, different heights or queries give a mixed result).
    InputDigest digest;
    digest.add(static_cast<long long>(sizeof(Float)));
    digest.add(std::vector<double>{double(batch.resolution), double(batch.channels), double(int(options.path)),
                                   options.tolerance, options.prune_tolerance, double(count)});
    for (const Heightfield& hf : heightfields) {
        digest.add(std::vector<double>{double(hf.rows()), double(hf.cols()), hf.texel_um(), hf.vscale()});
        digest.add(hf.values());
    }
    for (const auto& band : batch.bands) digest.add(band);
    for (const BatchItem& item : batch.items)
        digest.add(std::vector<double>{item.query.x_um, item.query.y_um, item.query.sigma_p_um, item.query.omega_i[0],
                                       item.query.omega_i[1], double(int(item.query.model)), double(item.band),
                                       double(item.heightfield)});
    agree_on_inputs(comm, digest.value(), "slices to render (heightfields, queries or options)");
    run_agreed(comm, [&] {
        if (heightfields.empty()) throw std::invalid_argument("no heightfields given; expected at least one");
        validate(batch, heightfields.size(), options);
        if (comm.is_root())
            out = allocating("the batch's output", double(values) * double(count) * sizeof(Float),
                             [&] { return std::vector<Float>(values * count); });
        local = render_batch<Float>(heightfields, part, options);
    });
    // Rounds of `chunk` items per rank (the gather's buffer on rank 0 at most ~2^24 values).
    const std::size_t chunk = std::max<std::size_t>(1,
                                                    (std::size_t(1) << 24) / std::max<std::size_t>(1, values * ranks));
    const std::size_t largest = share_of(count, 0, comm.size()).size();  // rank 0's block is the largest
    for (std::size_t start = 0; start < largest; start += chunk) {
        const std::size_t from = std::min(start, mine.size()), to = std::min(start + chunk, mine.size());
        const std::vector<double> piece(local.begin() + std::ptrdiff_t(from * values),
                                        local.begin() + std::ptrdiff_t(to * values));
        const std::vector<double> all = comm.gather(piece);
        if (!comm.is_root()) continue;
        std::size_t at = 0;
        for (int r = 0; r < comm.size(); ++r) {
            const Share block = share_of(count, r, comm.size());
            const std::size_t items = std::min(start + chunk, block.size()) - std::min(start, block.size());
            if (items == 0) continue;
            std::copy(all.begin() + std::ptrdiff_t(at), all.begin() + std::ptrdiff_t(at + items * values),
                      out.begin() + std::ptrdiff_t((block.begin + start) * values));
            at += items * values;
        }
    }
    return out;
}

template std::vector<float> render_batch_over_ranks<float>(const std::vector<Heightfield>&, const SliceBatch&,
                                                           const Communicator&, const RenderOptions&);
template std::vector<double> render_batch_over_ranks<double>(const std::vector<Heightfield>&, const SliceBatch&,
                                                             const Communicator&, const RenderOptions&);

}  // namespace wavebrdf
