// Rendering a BRDF table (table.h): the light grid, the memory estimate and the per-light loop.
// The file is src/io/exr_table.cpp.
#include <algorithm>
#include <stdexcept>
#include <string>

#include "wavebrdf/batch.h"
#include "wavebrdf/interrupt.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/progress.h"
#include "wavebrdf/table.h"
#include "wavebrdf/text.h"
#include "wavebrdf/version.h"

namespace wavebrdf {

void validate(const TableSpec& spec) {
    Query light_free = spec.query;
    light_free.omega_i = {0.0, 0.0};
    validate(light_free);
    validate_resolution(spec.resolution);
    if (spec.lambdas_um.empty()) throw std::invalid_argument("no wavelengths given; expected at least one");
    if (spec.lambdas_um.size() > 256)
        throw std::invalid_argument(std::to_string(spec.lambdas_um.size()) +
                                    " wavelengths given; expected at most 256");
    for (double lambda : spec.lambdas_um) validate_lambda(lambda);
    const LightGrid& g = spec.lights;
    const long long n = spec.resolution;
    if (g.rows < 1 || g.cols < 1 || g.rows * n > k_max_table_side || g.cols * n > k_max_table_side)
        throw std::domain_error("light grid " + std::to_string(g.rows) + "x" + std::to_string(g.cols) + " of " +
                                std::to_string(n) + "x" + std::to_string(n) +
                                " slices is out of range; expected at least 1x1 lights and at most " +
                                std::to_string(k_max_table_side) + " pixels per side of the mosaic (lights * n)");
    if (!(g.max_sin > 0.0 && g.max_sin < 1.0))
        throw std::domain_error("light grid max sin theta " + format_shortest(g.max_sin) +
                                " is out of range; expected 0 < max_sin < 1");
}

void light_grid_axes(const LightGrid& grid, std::vector<double>& light_x, std::vector<double>& light_y,
                     std::vector<unsigned char>& rendered) {
    light_x.resize(static_cast<std::size_t>(grid.rows));
    light_y.resize(static_cast<std::size_t>(grid.cols));
    for (int a = 0; a < grid.rows; ++a) light_x[std::size_t(a)] = light_grid_omega(a, grid.rows, grid.max_sin);
    for (int b = 0; b < grid.cols; ++b) light_y[std::size_t(b)] = light_grid_omega(b, grid.cols, grid.max_sin);
    rendered.assign(static_cast<std::size_t>(grid.rows) * static_cast<std::size_t>(grid.cols), 0);
    const double r2 = grid.max_sin * grid.max_sin;
    for (int a = 0; a < grid.rows; ++a)
        for (int b = 0; b < grid.cols; ++b) {
            const double x = light_x[std::size_t(a)], y = light_y[std::size_t(b)];
            rendered[std::size_t(a) * std::size_t(grid.cols) + std::size_t(b)] = x * x + y * y <= r2 ? 1 : 0;
        }
}

namespace {

double table_values(const TableSpec& spec) {
    const double n = spec.resolution;
    return double(spec.lights.rows) * double(spec.lights.cols) * n * n * 3.0;
}

std::size_t rendered_count(const std::vector<unsigned char>& rendered) {
    std::size_t count = 0;
    for (unsigned char r : rendered) count += r;
    return count;
}

}  // namespace

double estimate_table_bytes(const Heightfield& heightfield, const TableSpec& spec, const RenderOptions& options) {
    Query query = spec.query;
    query.omega_i = {0.0, 0.0};
    return 2.0 * 4.0 * table_values(spec) +
           estimate_render_bytes(heightfield, query, spec.resolution, options, spec.double_precision ? 8 : 4, true);
}

long long table_work_units(const TableSpec& spec, const Communicator& comm) {
    std::vector<double> x, y;
    std::vector<unsigned char> rendered;
    light_grid_axes(spec.lights, x, y, rendered);
    const std::size_t lights = share_of(rendered_count(rendered), comm.rank(), comm.size()).size();
    return static_cast<long long>(lights) * work_units(spec.resolution) *
           static_cast<long long>(spec.lambdas_um.size());
}

// One row a of the light grid (the lights of that row that are rendered) as one batch: the
// items are spread over the threads (batch.h), and the extra memory is one row of slices.
std::vector<float> render_table_row(const Heightfield& heightfield, const TableSpec& spec,
                                    const std::vector<std::array<double, 2>>& lights, const RenderOptions& options) {
    const SliceBatch batch = batch_product(spec.query, lights, {{spec.query.x_um, spec.query.y_um}}, {spec.lambdas_um},
                                           spec.resolution, 3);
    if (!spec.double_precision) return render_batch<float>(heightfield, batch, options);
    const std::vector<double> full = render_batch<double>(heightfield, batch, options);
    return std::vector<float>(full.begin(), full.end());
}

namespace {

// Refuses (OutOfMemory) a table whose estimated peak exceeds options.max_memory_gb.
void require_table_memory(const Heightfield& heightfield, const TableSpec& spec, const RenderOptions& options) {
    require_memory(estimate_table_bytes(heightfield, spec, options), memory_limit(options.max_memory_gb),
                   "table (" + std::to_string(spec.lights.rows) + "x" + std::to_string(spec.lights.cols) +
                       " lights of " + std::to_string(spec.resolution) + "x" + std::to_string(spec.resolution) +
                       " slices)");
}

// The table's description without its values: the spec, the heightfield's geometry, the
// version and the light grid's axes and rendered mask (light_grid_axes). `spec` is validated.
BrdfTable table_description(const Heightfield& heightfield, const TableSpec& spec) {
    BrdfTable table;
    table.spec = spec;
    table.heightfield_rows = heightfield.rows();
    table.heightfield_cols = heightfield.cols();
    table.texel_um = heightfield.texel_um();
    table.vscale = heightfield.vscale();
    table.version = k_version;
    light_grid_axes(spec.lights, table.light_x, table.light_y, table.rendered);
    return table;
}

// render_brdf_table on several ranks: every rendered light one item of one batch (row-major),
// split over the ranks; rank 0 places the gathered slices.
BrdfTable render_brdf_table_over_ranks(const Heightfield& heightfield, const TableSpec& spec,
                                       const RenderOptions& options, const Communicator& comm) {
    BrdfTable table;
    run_agreed(comm, [&] {
        validate(spec);
        // Rank 0 holds the whole table; the others their block (render_batch checks it).
        if (comm.is_root()) require_table_memory(heightfield, spec, options);
        table = table_description(heightfield, spec);
    });
    const std::size_t cols = static_cast<std::size_t>(spec.lights.cols);
    std::vector<std::array<double, 2>> lights;
    std::vector<std::size_t> entries;  // the table entry (a · cols + b) of each light
    for (std::size_t a = 0; a < table.light_x.size(); ++a)
        for (std::size_t b = 0; b < cols; ++b)
            if (table.rendered[a * cols + b]) {
                lights.push_back({table.light_x[a], table.light_y[b]});
                entries.push_back(a * cols + b);
            }
    const SliceBatch batch = batch_product(spec.query, lights, {{spec.query.x_um, spec.query.y_um}}, {spec.lambdas_um},
                                           spec.resolution, 3);
    const std::size_t slice = static_cast<std::size_t>(spec.resolution) * static_cast<std::size_t>(spec.resolution) * 3;
    const std::vector<Heightfield> heightfields{heightfield};
    const auto place = [&](const auto& slices) {
        table.values = allocating("the table's values", 4.0 * table_values(spec), [&] {
            return std::vector<float>(static_cast<std::size_t>(table_values(spec)), 0.0f);
        });
        for (std::size_t k = 0; k < entries.size(); ++k)
            std::copy(slices.begin() + std::ptrdiff_t(k * slice), slices.begin() + std::ptrdiff_t((k + 1) * slice),
                      table.values.begin() + std::ptrdiff_t(entries[k] * slice));
    };
    if (spec.double_precision) {
        const std::vector<double> slices = render_batch_over_ranks<double>(heightfields, batch, comm, options);
        if (comm.is_root()) place(slices);
    } else {
        const std::vector<float> slices = render_batch_over_ranks<float>(heightfields, batch, comm, options);
        if (comm.is_root()) place(slices);
    }
    return table;
}

}  // namespace

BrdfTable render_brdf_table(const Heightfield& heightfield, const TableSpec& spec, const RenderOptions& options,
                            const Communicator& comm) {
    if (comm.size() > 1) return render_brdf_table_over_ranks(heightfield, spec, options, comm);
    validate(spec);
    require_table_memory(heightfield, spec, options);
    BrdfTable table = table_description(heightfield, spec);
    const std::size_t slice = static_cast<std::size_t>(spec.resolution) * static_cast<std::size_t>(spec.resolution) * 3;
    table.values = allocating("the table's values", 4.0 * table_values(spec),
                              [&] { return std::vector<float>(static_cast<std::size_t>(table_values(spec)), 0.0f); });
    const std::size_t cols = static_cast<std::size_t>(spec.lights.cols);
    for (std::size_t a = 0; a < table.light_x.size(); ++a) {
        check_interrupt();
        std::vector<std::array<double, 2>> lights;
        std::vector<std::size_t> columns;
        for (std::size_t b = 0; b < cols; ++b)
            if (table.rendered[a * cols + b]) {
                lights.push_back({table.light_x[a], table.light_y[b]});
                columns.push_back(b);
            }
        if (lights.empty()) continue;
        const std::vector<float> row = render_table_row(heightfield, spec, lights, options);
        for (std::size_t k = 0; k < columns.size(); ++k)
            std::copy(row.begin() + std::ptrdiff_t(k * slice), row.begin() + std::ptrdiff_t((k + 1) * slice),
                      table.values.begin() + std::ptrdiff_t((a * cols + columns[k]) * slice));
    }
    return table;
}

}  // namespace wavebrdf
