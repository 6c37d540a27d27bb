#pragma once
// What SIGINT, SIGTERM and SIGHUP do to the wavebrdf tool.
namespace wavebrdf::cli {

// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove the temporary files of atomic
// writes in progress (wavebrdf::remove_temporary_files) and then end the process by the same
// signal (its default action), so an interrupted command leaves neither a partial output nor a
// `*.tmp-PID-N` file. Call once, first thing in main.
void install_signal_cleanup();

// The command has returned its exit status: a signal from now on (mpiexec ends the other ranks
// when one exits non-zero, while they finalise MPI) still ends the process, but without the
// "stopped before the run finished" line, which would be untrue and, on a rank that fails
// alike, a second message for one error.
void mark_command_ended();

// A handled signal is ending the process (its handler is removing the temporaries and will print
// the "stopped" line): an error the command raises now (a write refused because the process is
// being stopped) is a consequence of the signal, not a second message to print.
bool stopping();

// While a GracefulStop lives, the first SIGINT or SIGTERM is only recorded (signal() returns
// it) so that a long loop can stop at its next safe point and save its work; a second one (or
// SIGHUP) ends the process as install_signal_cleanup describes. Not nestable.
class GracefulStop {
public:
    GracefulStop();
    ~GracefulStop();
    GracefulStop(const GracefulStop&) = delete;
    GracefulStop& operator=(const GracefulStop&) = delete;

    // The recorded signal number, 0 while none arrived.
    int signal() const;
};

}  // namespace wavebrdf::cli
