#pragma once
// What the HDF5 plugin's readers share (src/plugins/hdf5/): one mutex for every HDF5 call of the
// plugin (the library may be built without thread safety), HDF5's error printing silenced while
// we call it, identifiers closed on scope exit, and the check of a dataset's storage before it
// is read. Named namespace, inline: one mutex for the whole plugin.
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "wavebrdf/surface_file.h"

namespace wavebrdf::hdf5 {

// A Zygo datx file's surface from its bytes (surface_datx.cpp); `name` for messages.
MeasuredSurface read_datx(const std::string& data, const std::string& name);

// Throws std::runtime_error "<path>: <dataset>: <what>".
[[noreturn]] inline void fail(const std::string& path, const std::string& dataset, const std::string& what) {
    throw std::runtime_error(path + ": " + dataset + ": " + what);
}

inline std::mutex& hdf5_mutex() {
    static std::mutex m;
    return m;
}

// While alive: our HDF5 calls are serialised and HDF5 prints nothing to stderr (H5Eset_auto);
// the previous error handler comes back after.
class Hdf5Session {
public:
    Hdf5Session() : m_lock(hdf5_mutex()) {
        // No library shutdown at exit (before HDF5's first call initialises it): after a failed
        // open of a damaged file HDF5 1.10 keeps internal objects it cannot free and would print
        // "HDF5: infinite loop closing library" and a trace after our one-line error. Every
        // file we open is closed by us; the process's exit frees the rest.
        static const bool no_shutdown_at_exit = (H5dont_atexit(), true);
        (void)no_shutdown_at_exit;
        H5Eget_auto2(H5E_DEFAULT, &m_function, &m_data);
        H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    }
    ~Hdf5Session() { H5Eset_auto2(H5E_DEFAULT, m_function, m_data); }
    Hdf5Session(const Hdf5Session&) = delete;
    Hdf5Session& operator=(const Hdf5Session&) = delete;

private:
    std::lock_guard<std::mutex> m_lock;
    H5E_auto2_t m_function = nullptr;
    void* m_data = nullptr;
};

// An HDF5 identifier closed when it goes out of scope.
class Id {
public:
    Id() = default;
    Id(hid_t id, herr_t (*close)(hid_t)) : m_id(id), m_close(close) {}
    Id(Id&& other) noexcept : m_id(other.m_id), m_close(other.m_close) { other.m_id = -1; }
    Id& operator=(Id&& other) noexcept {
        std::swap(m_id, other.m_id);
        std::swap(m_close, other.m_close);
        return *this;
    }
    Id(const Id&) = delete;
    Id& operator=(const Id&) = delete;
    ~Id() {
        if (m_id >= 0 && m_close != nullptr) m_close(m_id);
    }
    hid_t get() const { return m_id; }
    // Gives up ownership (the caller closes it).
    hid_t release() {
        const hid_t id = m_id;
        m_id = -1;
        return id;
    }
    bool valid() const { return m_id >= 0; }

private:
    hid_t m_id = -1;
    herr_t (*m_close)(hid_t) = nullptr;
};

// Where a dataset's values are and whether they can be read safely, checked before any read:
// only compact, contiguous or chunked storage inside this file (no virtual dataset drawing on
// other files, no external raw storage such as /etc/passwd or a FIFO); chunks of the dataset's
// rank, each dimension 1 to the dataset's (a corrupt chunk dimension made HDF5 read out of
// bounds); every chunk written (a few bytes may not declare 1e8 chunks of fill values) or,
// contiguous, every byte; and every filter of the pipeline available in this HDF5 (named when
// missing, e.g. lzf from h5py). Returns the bytes of one chunk in memory (0 unless chunked).
inline double check_storage(hid_t dataset, const std::string& path, const char* name,
                            const std::vector<hsize_t>& dims) {
    Id dcpl(H5Dget_create_plist(dataset), H5Pclose);
    if (!dcpl.valid()) fail(path, name, "cannot read its storage layout");
    const H5D_layout_t layout = H5Pget_layout(dcpl.get());
    if (layout == H5D_VIRTUAL)
        fail(path, name,
             "is a virtual dataset (its values come from other datasets or files); expected its "
             "values stored in this file");
    if (layout != H5D_COMPACT && layout != H5D_CONTIGUOUS && layout != H5D_CHUNKED)
        fail(path, name, "has an unknown storage layout; expected compact, contiguous or chunked");
    const int external = H5Pget_external_count(dcpl.get());
    if (external != 0)
        fail(path, name,
             "has external raw storage (its values in " +
                 (external > 0 ? std::to_string(external) : std::string("some")) +
                 " other file(s)); expected its values stored in this file");
    const int filters = H5Pget_nfilters(dcpl.get());
    if (filters < 0) fail(path, name, "cannot read its filter pipeline");
    for (int k = 0; k < filters; ++k) {
        unsigned flags = 0, config = 0;
        std::size_t values = 0;
        char filter_name[64] = {};
        const H5Z_filter_t id = H5Pget_filter2(dcpl.get(), unsigned(k), &flags, &values, nullptr, sizeof filter_name,
                                               filter_name, &config);
        if (id < 0) fail(path, name, "cannot read its filter pipeline");
        if (H5Zfilter_avail(id) <= 0)
            fail(path, name,
                 "is compressed with HDF5 filter " + std::to_string(id) +
                     (filter_name[0] != '\0'
                          ? " (" + std::string(filter_name, strnlen(filter_name, sizeof filter_name)) + ")"
                          : std::string()) +
                     ", which this build's HDF5 does not have; expected gzip (deflate), shuffle or no compression");
    }
    Id type(H5Dget_type(dataset), H5Tclose);
    const double value_bytes = type.valid() ? double(H5Tget_size(type.get())) : 8.0;
    double count = 1.0;
    for (hsize_t d : dims) count *= double(d);
    if (layout == H5D_CONTIGUOUS) {
        const double expected = count * value_bytes;
        const double stored = double(H5Dget_storage_size(dataset));
        if (stored < expected)
            fail(path, name,
                 "holds " + std::to_string(static_cast<long long>(stored)) + " of its " +
                     std::to_string(static_cast<long long>(expected)) + " bytes (never written, or damaged)");
        return 0.0;
    }
    if (layout != H5D_CHUNKED) return 0.0;
    std::vector<hsize_t> chunk(dims.size() + 1, 0);
    if (H5Pget_chunk(dcpl.get(), int(chunk.size()), chunk.data()) != int(dims.size()))
        fail(path, name, "has chunks of another rank than the dataset's " + std::to_string(dims.size()));
    double chunks = 1.0, elements = 1.0;
    for (std::size_t k = 0; k < dims.size(); ++k) {
        if (chunk[k] < 1 || chunk[k] > std::max<hsize_t>(dims[k], 1))
            fail(path, name,
                 "has a chunk dimension " + std::to_string(chunk[k]) + " on axis " + std::to_string(k) +
                     " where the dataset has " + std::to_string(dims[k]) +
                     "; expected chunks of 1 to the dataset's size per axis (damaged file?)");
        chunks *= std::ceil(double(dims[k]) / double(chunk[k]));
        elements *= double(chunk[k]);
    }
#if H5_VERSION_GE(1, 10, 5)
    if (count > 0.0) {
        hsize_t written = 0;
        Id space(H5Dget_space(dataset), H5Sclose);
        if (!space.valid() || H5Dget_num_chunks(dataset, space.get(), &written) < 0)
            fail(path, name, "cannot count its chunks");
        if (double(written) < chunks)
            fail(path, name,
                 "holds " + std::to_string(written) + " of its " + std::to_string(static_cast<long long>(chunks)) +
                     " chunks (never written, or damaged); expected every value stored");
    }
#endif
    return elements * 8.0;
}

}  // namespace wavebrdf::hdf5
