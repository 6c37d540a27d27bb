// NumPy leading batch axes for render_slice and slice_gradient (batch.h): the broadcast rule,
// its checks (ValueError naming the argument and the shapes), the memory bound before anything
// is allocated, and the library's batch API (wavebrdf/batch.h), threaded across the batch,
// without the GIL and interruptible.
#include "batch.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "wavebrdf/batch.h"
#include "wavebrdf/input_digest.h"
#include "wavebrdf/memory.h"
#include "wavebrdf/model.h"

namespace wavebrdf::python {

using namespace pybind11::literals;

const char* const kBatchDoc = R"doc(
Batches: heights may have leading batch axes (..., rows, cols); light may be (2,) or (..., 2);
x_um and y_um may be scalars or arrays. The batch shape is the NumPy broadcast of
heights.shape[:-2], light.shape[:-1], numpy.shape(x_um) and numpy.shape(y_um) (right-aligned;
each axis equal or 1), and item [i...] renders heights[i...], light[i...], x_um[i...], y_um[i...]
with each argument indexed as broadcasting repeats it. render_slice returns (batch..., n, n, 3);
slice_gradient takes weights of exactly that shape and returns an array shaped like heights
whose entries sum the gradients of every item that read them (so heights broadcast over lights
get the sum over the lights). sigma_p_um, the wavelengths and the model are shared. The items
run in one library call spread over the threads (wavebrdf/batch.h); each equals the single call
(to rounding of a parallel sum, ~1e-12 relative in float64). A single query (2-D heights, one
light pair, scalar positions) keeps the shapes (n, n, 3) and (rows, cols).
The last two axes of heights are always one surface. With batch axes, a surface that looks like
an image's channels is refused (ValueError): 1 texel wide, or 2 to 4 texels wide and at least 4
times longer, when that is narrower than the footprint (6 sigma_p) or is the last axis of an
(H, W, C) array with H and W both at least 4 C. For an image-like export (rows, cols, 1 to 4)
pass heights[..., 0]; narrow surfaces of a real batch render one 2-D array at a time.
)doc";

namespace {

using Shape = std::vector<py::ssize_t>;

py::array coordinates(py::handle object, const char* name) {
    py::array a;
    try {
        a = py::module_::import("numpy").attr("asarray")(object, "dtype"_a = "float64");
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
        throw py::value_error(std::string(name) + " = " + std::string(py::repr(object)) +
                              " is invalid; expected a number or an array of numbers");
    }
    return a;
}

Shape shape_of(const py::array& a, py::ssize_t drop_last = 0) {
    return Shape(a.shape(), a.shape() + (a.ndim() - drop_last));
}

// The NumPy broadcast of the named shapes, or a ValueError naming them all.
Shape broadcast(const std::vector<std::pair<const char*, Shape>>& shapes) {
    std::size_t ndim = 0;
    for (const auto& s : shapes) ndim = std::max(ndim, s.second.size());
    Shape out(ndim, 1);
    for (const auto& s : shapes)
        for (std::size_t k = 0; k < s.second.size(); ++k) {
            const std::size_t at = ndim - s.second.size() + k;
            const py::ssize_t extent = s.second[k];
            if (extent == out[at] || extent == 1) continue;
            if (out[at] == 1) {
                out[at] = extent;
                continue;
            }
            std::string what;
            for (const auto& t : shapes)
                what += (what.empty() ? "" : ", ") + std::string(t.first) + " " + shape_string(t.second);
            throw py::value_error("batch shapes do not broadcast: " + what +
                                  " (heights without its last two axes, light without its last; each axis equal "
                                  "or 1)");
        }
    return out;
}

// The flat index into an argument of batch shape `shape` (right-aligned, size-1 axes repeat) of
// the item with multi-index `index` in the batch shape.
std::size_t broadcast_index(const Shape& index, const Shape& shape) {
    std::size_t flat = 0;
    const std::size_t offset = index.size() - shape.size();
    for (std::size_t k = 0; k < shape.size(); ++k)
        flat = flat * static_cast<std::size_t>(shape[k]) +
               (shape[k] == 1 ? 0 : static_cast<std::size_t>(index[offset + k]));
    return flat;
}

double product(const Shape& shape) {
    double p = 1.0;
    for (py::ssize_t e : shape) p *= double(e);
    return p;
}

// Batch axes lead: the last two axes are one surface, any before them a batch. An image-like
// export, (H, W, 1) or (H, W, C) with C <= 4 colour channels, would otherwise read as H surfaces
// of W x C texels, and render without complaint. A periodic tile smaller than the footprint is
// valid (the model takes each texel once, at its nearest periodic copy), so small square tiles
// pass; what is refused is a surface in a batch that is 1 texel wide, or 2 to 4 texels wide, at
// least 4 times longer than wide, and either narrower than the footprint (6 sigma_p, the
// renderer's cut at 3 sigma_p both sides) or shaped as an image's channels (the last axis, with
// the axis before the surface as long as the rows). A 2-D array is one surface, never refused here.
void check_batch_surfaces(const py::array& heights, double texel_um, double sigma_p_um) {
    const py::ssize_t nd = heights.ndim();
    if (nd < 3) return;
    const py::ssize_t rows = heights.shape(nd - 2), cols = heights.shape(nd - 1), lead = heights.shape(nd - 3);
    const py::ssize_t narrow = std::min(rows, cols), wide = std::max(rows, cols);
    const double footprint_texels = 6.0 * sigma_p_um / texel_um;
    std::string why;
    if (narrow == 1)
        why = "1 texel wide";
    else if (narrow <= 4 && wide >= 4 * narrow && double(narrow) < footprint_texels)
        why = "narrower than the footprint (6 sigma_p = " + format_number(6.0 * sigma_p_um) + " um, " +
              format_number(footprint_texels) + " texels) and " + std::to_string(wide / narrow) +
              " times longer than wide";
    else if (cols <= 4 && rows >= 4 * cols && lead >= 4 * cols)
        why = "shaped as an image's colour channels (rows, cols, " + std::to_string(cols) + ")";
    if (why.empty()) return;
    throw py::value_error("heights has shape " + shape_string(heights) + ", read as a batch " +
                          shape_string(shape_of(heights, 2)) + " of " + std::to_string(rows) + "x" +
                          std::to_string(cols) +
                          " surfaces (batch axes lead: (..., rows, cols), the last two axes "
                          "are one surface); a " +
                          std::to_string(rows) + "x" + std::to_string(cols) + " surface is " + why +
                          "; expected one surface per (rows, cols): for one surface stored as (rows, cols, "
                          "channels), pass heights[..., 0] (or a mean over the channels); a batch of narrow "
                          "surfaces renders one 2-D array at a time");
}

struct Batched {
    py::array heights;
    bool single = false;  // float32
    Shape batch_shape;
    std::vector<Heightfield> heightfields;
    SliceBatch batch;
    int rows = 0, cols = 0;
};

Batched batched_arguments(py::handle heights_object, int resolution, double texel_um, double vscale, py::handle x_um,
                          py::handle y_um, double sigma_p_um, const py::object& lambda_um, const py::object& spectral,
                          py::handle light_object, const std::string& model, bool gradient) {
    Batched a;
    a.heights = float_array(heights_object, "heights");
    a.single = is_float32(a.heights);
    const py::ssize_t nd = a.heights.ndim();
    if (nd < 2 || a.heights.shape(nd - 1) == 0 || a.heights.shape(nd - 2) == 0)
        throw py::value_error("heights has shape " + shape_string(a.heights) +
                              "; expected (..., rows, cols) with rows, cols >= 1 (heights in texel units)");
    check_resolution(resolution);
    check_positive(texel_um, "texel_um");
    check_finite(vscale, "vscale");
    const py::array x = coordinates(x_um, "x_um"), y = coordinates(y_um, "y_um");
    const std::vector<double> xs = to_doubles(x, "x_um"), ys = to_doubles(y, "y_um");
    check_positive(sigma_p_um, "sigma_p_um");
    check_batch_surfaces(a.heights, texel_um, sigma_p_um);
    Query base;
    base.sigma_p_um = sigma_p_um;
    const std::vector<double> lambdas = wavelengths(lambda_um, spectral);
    const py::array light = coordinates(light_object, "light");
    if (light.ndim() == 0 || light.shape(light.ndim() - 1) != 2)
        throw py::value_error("light has shape " + shape_string(light) + "; expected (2,) or (..., 2): (wx, wy) pairs");
    const std::vector<double> ls = to_doubles(light, "light");
    for (std::size_t k = 0; k < ls.size(); k += 2)
        if (ls[k] * ls[k] + ls[k + 1] * ls[k + 1] >= 1.0)
            bad_argument("light[" + std::to_string(k / 2) + "] (flat index)",
                         "(" + format_number(ls[k]) + ", " + format_number(ls[k + 1]) + ")",
                         "a projected direction towards the light with wx^2 + wy^2 < 1");
    base.model = model_from(model);

    const Shape heights_shape = shape_of(a.heights, 2), light_shape = shape_of(light, 1);
    const Shape x_shape = shape_of(x), y_shape = shape_of(y);
    a.batch_shape = broadcast(
        {{"heights", heights_shape}, {"light", light_shape}, {"x_um", x_shape}, {"y_um", y_shape}});
    a.rows = static_cast<int>(a.heights.shape(nd - 2));
    a.cols = static_cast<int>(a.heights.shape(nd - 1));
    // Bound what this call allocates before allocating it: the items, their output (and
    // weights and a gradient per item for the gradient), in double so no product overflows.
    const double items = product(a.batch_shape), n = double(resolution);
    const double per_item = double(sizeof(BatchItem)) + n * n * 3.0 * (a.single ? 4.0 : 8.0) +
                            (gradient ? n * n * 3.0 * 8.0 + double(a.rows) * double(a.cols) * 8.0 : 0.0);
    const MemoryLimit limit = memory_limit(0.0);
    require_memory(items * per_item + product(heights_shape) * double(a.rows) * double(a.cols) * 16.0, limit,
                   std::string(gradient ? "slice_gradient" : "render_slice") + " of batch shape " +
                       shape_string(a.batch_shape) + " at resolution " + std::to_string(resolution),
                   "smaller batches");

    const std::size_t cells = static_cast<std::size_t>(a.rows) * static_cast<std::size_t>(a.cols);
    {
        std::vector<double> all = to_doubles(a.heights, "heights");
        const auto count = static_cast<std::size_t>(product(heights_shape));
        a.heightfields.reserve(count);
        for (std::size_t k = 0; k < count; ++k)
            a.heightfields.emplace_back(a.rows, a.cols,
                                        std::vector<double>(all.begin() + static_cast<std::ptrdiff_t>(k * cells),
                                                            all.begin() + static_cast<std::ptrdiff_t>((k + 1) * cells)),
                                        texel_um, vscale);
    }
    a.batch.bands = {lambdas};
    a.batch.resolution = resolution;
    a.batch.channels = 3;
    const auto count = static_cast<std::size_t>(items);
    a.batch.items.resize(count);
    Shape index(a.batch_shape.size(), 0);
    for (std::size_t b = 0; b < count; ++b) {
        BatchItem& item = a.batch.items[b];
        item.query = base;
        item.heightfield = broadcast_index(index, heights_shape);
        const std::size_t l = broadcast_index(index, light_shape);
        item.query.omega_i = {ls[2 * l], ls[2 * l + 1]};
        item.query.x_um = xs[broadcast_index(index, x_shape)];
        item.query.y_um = ys[broadcast_index(index, y_shape)];
        for (std::size_t k = index.size(); k-- > 0;) {  // next multi-index, last axis fastest
            if (++index[k] < a.batch_shape[k]) break;
            index[k] = 0;
        }
    }
    return a;
}

Shape with(Shape shape, std::initializer_list<py::ssize_t> tail) {
    shape.insert(shape.end(), tail);
    return shape;
}

template <typename Float>
py::object render(const Batched& a, const RenderOptions& options, const Communicator* comm) {
    std::vector<Float> out;
    if (comm != nullptr) {
        {
            InterruptibleRelease release;
            out = render_batch_over_ranks<Float>(a.heightfields, a.batch, *comm, options);
        }
        if (!comm->is_root()) return py::none();  // rank 0 gathers the slices
    } else if (!a.batch.items.empty()) {
        InterruptibleRelease release;
        out = render_batch<Float>(a.heightfields, a.batch, options);
    }
    const py::ssize_t n = a.batch.resolution;
    return owning_array(std::move(out), with(a.batch_shape, {n, n, 3}));
}

template <typename Float>
py::array gradient_of(const Batched& a, const std::vector<double>& weights, const RenderOptions& options) {
    std::vector<std::vector<double>> gradients(a.heightfields.size());
    if (!a.batch.items.empty()) {
        InterruptibleRelease release;
        batch_gradient<Float>(a.heightfields, a.batch, weights, gradients, options);
    }
    const std::size_t cells = static_cast<std::size_t>(a.rows) * static_cast<std::size_t>(a.cols);
    std::vector<Float> out(gradients.size() * cells);
    for (std::size_t k = 0; k < gradients.size(); ++k)
        for (std::size_t c = 0; c < gradients[k].size(); ++c) out[k * cells + c] = static_cast<Float>(gradients[k][c]);
    return owning_array(std::move(out), shape_of(a.heights));
}

}  // namespace

std::vector<double> slice_weights(const py::array& w, int n, const char* name) {
    std::vector<double> values = to_doubles(w, name, false);
    const std::size_t pixels = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    std::vector<unsigned char> inside(pixels, 0);
    for (int p = 0; p < n; ++p)
        for (const DiskPixel pixel : disk_row(p, n)) inside[std::size_t(p) * std::size_t(n) + std::size_t(pixel.q)] = 1;
    std::size_t bad = values.size();
    for (std::size_t k = 0; k < values.size(); ++k) {
        if (!inside[(k / 3) % pixels])
            values[k] = 0.0;
        else if (!std::isfinite(values[k]) && bad == values.size())
            bad = k;
    }
    if (bad != values.size()) {
        // The index in the array's own shape, e.g. [3, 4, 0].
        std::string index;
        std::size_t rest = bad;
        for (py::ssize_t d = w.ndim() - 1; d >= 0; --d) {
            const auto extent = static_cast<std::size_t>(w.shape(d));
            index = std::to_string(rest % extent) + (index.empty() ? "" : ", ") + index;
            rest /= extent;
        }
        throw py::value_error(std::string(name) + "[" + index + "] = " + format_number(values[bad]) +
                              " is not finite; expected finite values inside the unit disk (pixels outside it are "
                              "ignored)");
    }
    return values;
}

bool single_query(py::handle heights, py::handle x_um, py::handle y_um, py::handle light) {
    const auto ndim = [](py::handle o) -> py::ssize_t {
        if (py::isinstance<py::array>(o)) return py::reinterpret_borrow<py::array>(o).ndim();
        try {
            return py::module_::import("numpy").attr("ndim")(o).cast<py::ssize_t>();
        } catch (py::error_already_set&) {
            return 0;  // not array-like: the single path names the argument
        }
    };
    return ndim(heights) <= 2 && ndim(light) <= 1 && ndim(x_um) == 0 && ndim(y_um) == 0;
}

py::object render_slice_batch(py::handle heights, int resolution, double texel_um, double vscale, py::handle x_um,
                              py::handle y_um, double sigma_p_um, const py::object& lambda_um,
                              const py::object& spectral, py::handle light, const std::string& model,
                              const RenderOptions& options, const Communicator* comm) {
    if (comm == nullptr) {
        const Batched a = batched_arguments(heights, resolution, texel_um, vscale, x_um, y_um, sigma_p_um, lambda_um,
                                            spectral, light, model, false);
        return a.single ? render<float>(a, options, nullptr) : render<double>(a, options, nullptr);
    }
    // Over ranks: a bad argument on one rank fails every rank (an agreement before the first
    // collective), and the ranks must have been given the same batch (a digest of it).
    Batched a;
    run_agreed(*comm, [&] {
        a = batched_arguments(heights, resolution, texel_um, vscale, x_um, y_um, sigma_p_um, lambda_um, spectral, light,
                              model, false);
    });
    InputDigest d;
    d.add(static_cast<long long>(resolution));
    d.add(std::vector<double>(a.batch_shape.begin(), a.batch_shape.end()));
    d.add(static_cast<long long>(a.single));
    for (const Heightfield& hf : a.heightfields) {
        d.add(std::vector<double>{double(hf.rows()), hf.texel_um(), hf.vscale()});
        d.add(hf.values());
    }
    for (const BatchItem& item : a.batch.items)
        d.add(std::vector<double>{item.query.x_um, item.query.y_um, item.query.sigma_p_um, item.query.omega_i[0],
                                  item.query.omega_i[1], double(int(item.query.model)), double(item.heightfield)});
    for (const auto& band : a.batch.bands) d.add(band);
    agree_on_inputs(*comm, d.value(), "arguments (heights, positions, lights, options)");
    return a.single ? render<float>(a, options, comm) : render<double>(a, options, comm);
}

py::array slice_gradient_batch(py::handle heights, py::handle weights, int resolution, double texel_um, double vscale,
                               py::handle x_um, py::handle y_um, double sigma_p_um, const py::object& lambda_um,
                               const py::object& spectral, py::handle light, const std::string& model,
                               const RenderOptions& options) {
    const Batched a = batched_arguments(heights, resolution, texel_um, vscale, x_um, y_um, sigma_p_um, lambda_um,
                                        spectral, light, model, true);
    const py::array w = float_array(weights, "weights");
    const py::ssize_t n = resolution;
    const Shape expected = with(a.batch_shape, {n, n, 3});
    check_shape(w, expected, "weights");
    const std::vector<double> values = slice_weights(w, resolution, "weights");
    return a.single ? gradient_of<float>(a, values, options) : gradient_of<double>(a, values, options);
}

}  // namespace wavebrdf::python
