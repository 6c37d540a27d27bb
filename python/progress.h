#pragma once
// Progress of wavebrdf.invert and wavebrdf.recover shown from Python (wavebrdf/_progress.py:
// tqdm, else a line on stderr, or nothing): the user's callback is wrapped by the package so
// that each epoch or step also advances the display, and the display is closed however the run
// ends.
#include <string>

#include "common.h"

namespace wavebrdf::python {

// `quiet` must be None, True or False (ValueError naming it otherwise); call before any work.
inline void check_quiet(const py::object& quiet) {
    if (!quiet.is_none() && !py::isinstance<py::bool_>(quiet))
        throw py::value_error("quiet = " + std::string(py::repr(quiet)) +
                              " is invalid; expected True (no progress), False (progress) or None (progress "
                              "when stderr is a terminal or in Jupyter)");
}

class PythonProgress {
public:
    // wavebrdf._progress.<wrapper>(callback, quiet, total); with the GIL held.
    PythonProgress(const char* wrapper, const py::object& callback, const py::object& quiet, const py::object& total) {
        init(py::module_::import("wavebrdf._progress").attr(wrapper)(callback, quiet, total));
    }
    // wavebrdf._progress.<wrapper>(callback, quiet).
    PythonProgress(const char* wrapper, const py::object& callback, const py::object& quiet) {
        init(py::module_::import("wavebrdf._progress").attr(wrapper)(callback, quiet));
    }
    PythonProgress(const PythonProgress&) = delete;
    PythonProgress& operator=(const PythonProgress&) = delete;
    // Closes the display; the GIL must be held (declare it outside the released sections).
    ~PythonProgress() { close(); }

    // The callback to run with: the user's wrapped, or the user's itself when nothing is shown.
    const py::object& callback() const { return m_callback; }

    // Ends the display's line; an error pending (Ctrl-C's KeyboardInterrupt) stays pending,
    // and a failure of the display itself is ignored (the run's outcome matters, not the bar).
    void close() noexcept {
        if (m_display.is_none()) return;
        py::error_scope pending;
        try {
            m_display.attr("close")();
        } catch (...) {}
        m_display = py::none();
    }

private:
    void init(const py::tuple& wrapped) {
        m_callback = wrapped[0];
        m_display = wrapped[1];
    }
    py::object m_callback = py::none();
    py::object m_display = py::none();
};

}  // namespace wavebrdf::python
