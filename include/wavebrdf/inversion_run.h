#pragma once
// One inversion as `wavebrdf invert` and the Python module's invert() run it, so that both
// share one implementation (as recovery_run.h does for recover): the options as values, their
// texts parsed once (positions, init, snapshots, optimiser), the set-up (a given, read or
// generated truth; observations rendered from it or given; the initial guess), the memory
// check, the run with an epoch callback and a status instead of an exit, and the run
// directory (run.json both ways, metrics.csv, snapshots, checkpoints, final renders, resume).
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "wavebrdf/heightfield.h"
#include "wavebrdf/invert.h"
#include "wavebrdf/loss.h"
#include "wavebrdf/model.h"
#include "wavebrdf/observation.h"
#include "wavebrdf/optim.h"
#include "wavebrdf/option_style.h"

namespace wavebrdf {

// Where the footprints of an inversion are.
enum class PositionsKind {
    Fixed,   // one observation at options.x_um / y_um (default: the tile centre)
    Random,  // a new position every epoch (PositionMode::Random)
    List,    // one observation per listed position
};

struct PositionsSpec {
    PositionsKind kind = PositionsKind::Fixed;
    std::vector<std::array<double, 2>> positions_um;  // List: footprint centres (x, y), µm
    std::string path;  // List read from a JSON file: that file (as given); empty for a list of values
};

// "fixed", "random" or a JSON file of positions (read_positions_json: its messages name the
// file). Throws std::runtime_error for a file that cannot be read or is not a list of pairs.
// `name` is unused by the file's messages and kept for symmetry with the other parsers.
PositionsSpec parse_positions_spec(const std::string& text, const std::string& name = "positions");
// "fixed", "random", the file's path, or "list" for a list of values.
std::string to_string(const PositionsSpec& positions);

// The initial guess of an inversion.
enum class InitKind {
    Flat,     // zeros
    Noisy,    // the truth plus uniform noise (noisy_start), needs a truth
    File,     // heights read from an EXR (path), with the options' texel width and vscale
    Heights,  // heights given to prepare_inversion (Python's Heightfield or array)
};

struct InitSpec {
    InitKind kind = InitKind::Flat;
    double noise_fraction = 0.0;  // Noisy: 0 … kMaxNoiseFraction
    std::string path;             // File
    std::string text;             // Noisy: the text it was parsed from ("noisy:0.1"), for run.json and messages
};

// "flat", "noisy:FRAC" or an EXR path (read later, by prepare_inversion). Throws
// std::invalid_argument "NAME 'TEXT' is invalid; expected flat, noisy:FRAC or FILE.exr" for a
// FRAC that is not a number and std::domain_error "NAME noisy:FRAC: ..." for one outside
// 0 … kMaxNoiseFraction (`name` is the option, e.g. "--init" or "init").
InitSpec parse_init_spec(const std::string& text, const std::string& name = "init");
// "flat", the noisy text, the path, or "heights".
std::string to_string(const InitSpec& init);

// A comma-separated list of epochs ≥ 0 ("0,10,30"). Throws std::invalid_argument
// "NAME 'TEXT' is invalid; expected epochs like 0,10,30".
std::set<int> parse_epoch_list(const std::string& text, const std::string& name = "snapshots");
// The list as parse_epoch_list reads it ("0,10,30").
std::string format_epoch_list(const std::set<int>& epochs);

// "adam" or "lbfgs". Throws std::invalid_argument "NAME 'TEXT' is unknown; expected adam or lbfgs".
OptimizerKind parse_optimizer(const std::string& text, const std::string& name = "optimizer");
const char* to_string(OptimizerKind optimizer);

// "N" or "NxM" (also "NXM") → rows, cols, 1 … 16384 each. Throws std::invalid_argument naming
// `name` and the text.
void parse_size(const std::string& name, const std::string& text, int& rows, int& cols);

// Every option of `wavebrdf invert` (its defaults), as values.
struct InversionOptions {
    std::string truth_path;         // EXR of the truth; empty: given to prepare_inversion, or generated
    std::string observations_path;  // observations JSON or HDF5 (observation_file.h); empty: none (or given)
    // A slice EXR (read_slice_exr; its R channel for one wavelength, RGB for several) as the one
    // observation, with this query: x_um, y_um (none: the tile centre), sigma_p_um, omega_i,
    // model, the wavelengths, and resolution = the image's n (the CLI fills what is not given
    // from the slice's attributes). Excludes truth_path and observations_path.
    std::string reference_path;
    // With reference_path: its per-pixel weights, an EXR of n × n pixels (R channel; finite,
    // ≥ 0, not all 0; Observation::weights). Empty: every pixel weighs 1.
    std::string weights_path;
    // The generated truth's grid (default_inversion_truth), and the estimate's with observations.
    int rows = 16, cols = 16;
    double texel_um = 1.0, vscale = 1.0;  // of the truth read or generated, and of the estimate
    std::optional<double> x_um, y_um;     // footprint centre, µm, finite; none: the tile centre
    double sigma_p_um = 4.0;
    Model model = Model::OHS;
    // The wavelengths: one (lambda_um, µm: one channel), spectral N samples (CIE 1931 → linear
    // sRGB, 1 … 256), or a list (wavelengths_um, Python's spectral=[...] or a reference
    // slice's). At most one of them; none: spectral 8.
    std::optional<double> lambda_um;
    std::optional<int> spectral;
    std::vector<double> wavelengths_um;
    std::array<double, 2> omega_i{{0.0, 0.0}};  // projected light direction ω_i (--light-x/-y), |ω_i| < 1
    int resolution = 32;                        // slice size n, 1 … 8192
    int epochs = 300;                           // 0 … k_max_iterations
    OptimizerKind optimizer = OptimizerKind::Adam;
    AdamOptions adam;  // lr, beta1, beta2, decay (epsilon is Adam's)
    Loss loss;         // cmsle:1
    PositionsSpec positions;
    InitSpec init;
    std::uint64_t seed = 1;  // generated truth, noise, random positions
    // The rendering path and its error bound (RenderOptions' path and tolerance, 1e-12 … 1e-2),
    // for every forward and gradient; in run.json as "path" ("auto", ...) and "tolerance"
    // (an older run.json without them reads back as auto and 1e-6).
    RenderPath path = RenderPath::Auto;
    double tolerance = 1e-6;
    // Run directory only: epochs whose heights, slices and gradients are kept, and the epochs
    // between checkpoints (≥ 1).
    std::set<int> snapshots{0, 10, 30, 100, 300};
    int checkpoint_every = 50;
    // Refuse (OutOfMemory, before rendering) a run whose estimated peak memory exceeds this
    // many GB; 0: the physical memory. Not stored in run.json (a resumed run may change it).
    double max_memory_gb = 0.0;
    OptionStyle names = OptionStyle::Cli;  // how messages name the options
    // The ranks the run is split over (communicator.h; not in run.json): null, serial. Each rank
    // renders (or, given, keeps) only its share of the observations (observation_share by
    // footprint position); every function below that takes these options is then collective.
    const Communicator* communicator = nullptr;
};

// Everything an inversion needs, resolved.
struct PreparedInversion {
    std::optional<Heightfield> truth;       // given, read or generated; none with observations
    std::vector<Observation> observations;  // given, read, or rendered from the truth
    Heightfield initial{1, 1, {0.0}};       // the initial guess (texel width and vscale of the estimate)
    InversionSettings settings;
    // Which of all the observations `observations` are (this rank's share; serial: all of them).
    ObservationShard shard;
};

// The set-up, all options checked before any work (bad values throw std::invalid_argument or
// std::domain_error naming the option in options.names' style): the truth is `truth` when
// given, else read from options.truth_path, else generated (default_inversion_truth), unless
// observations are given (`observations`, or read from options.observations_path); the
// observations of a truth are rendered at the positions (observe), after the memory check
// (estimate_inversion_bytes against options.max_memory_gb: OutOfMemory); the initial guess is
// options.init (`initial` for InitKind::Heights, same size as the estimate). Throws
// std::invalid_argument when a truth and observations are both given. With options.communicator
// of several ranks: `observations` (given whole) are cut to this rank's share, a truth's are
// rendered for the share only, the memory check counts the share, and errors are agreed
// (run_agreed: RankFailed on every rank, communicator.h).
PreparedInversion prepare_inversion(const InversionOptions& options, std::optional<Heightfield> truth = {},
                                    std::optional<std::vector<Observation>> observations = {},
                                    std::optional<Heightfield> initial = {});

enum class InversionStatus {
    Completed,  // every epoch ran
    Stopped,    // the callback (or the stop predicate) asked to stop; the state is consistent for a checkpoint
};

// One prepared inversion. Not copyable or movable (the Inversion refers to the truth it holds).
class InversionRun {
public:
    explicit InversionRun(PreparedInversion prepared);
    InversionRun(const InversionRun&) = delete;
    InversionRun& operator=(const InversionRun&) = delete;

    // Runs to settings.epochs (or from a loaded checkpoint on). on_epoch as Inversion::run's;
    // returning false stops: Stopped (split over ranks: false on any rank stops every rank at
    // that epoch). Exceptions of the run and the callback propagate.
    InversionStatus run(const Inversion::Callback& on_epoch = {});

    const PreparedInversion& prepared() const { return m_prepared; }
    Inversion& inversion() { return m_inversion; }
    const Inversion& inversion() const { return m_inversion; }

private:
    PreparedInversion m_prepared;
    Inversion m_inversion;
};

// --- run directory (`wavebrdf invert --out DIR`, `--resume DIR`) ------------------------------

// run.json's "args" object for `options` as JSON text (input files by absolute path, so that
// a resume finds them from any directory). Throws std::invalid_argument for options that
// run.json cannot hold (a list of positions given as values, given heights).
std::string inversion_options_to_json(const InversionOptions& options);
// The options of run.json's "args" (JSON text). Throws std::runtime_error "WHERE: corrupt (...)"
// for JSON that is not such an object, "WHERE: field 'NAME' is ...; expected an integer from
// MIN to MAX" for an integer field that is not one, and the parsers' errors for its texts.
InversionOptions inversion_options_from_json(const std::string& text, const std::string& where = "run.json");

// metrics.csv: a header and one row per epoch, 10 significant digits.
std::string metrics_csv(const std::vector<EpochMetrics>& history);

struct InversionDirectoryControl {
    bool force = false;          // a new run may replace an earlier one of invert's (run_directory.h)
    bool show_progress = false;  // an "invert" progress bar on a terminal
    // Polled after each epoch's outputs: true stops the run with a checkpoint (Stopped). Split
    // over ranks: the run stops when it is true on any rank (Communicator::any, every epoch).
    std::function<bool()> stop;
    // resume_inversion_in_directory's ranks (a new run takes options.communicator); null: serial.
    const Communicator* communicator = nullptr;
};

struct InversionDirectoryResult {
    InversionStatus status = InversionStatus::Completed;
    int epoch = 0;                      // the last epoch reached
    std::vector<EpochMetrics> history;  // metrics.csv's rows
};

// A new run in `dir` (check_run_directory's rule, `force` from control): prepare_inversion,
// then run.json, the references (reference.npy, reference_NNN.exr/png), the truth
// (truth_height.npy, truth.exr), the run with snapshots (snapshots/*_EEEE.npy for the epochs
// of options.snapshots), checkpoint.json and metrics.csv every options.checkpoint_every
// epochs and at the end, then estimate.exr/png and final_NNN.exr/png. Nothing is written
// before every option is checked and the set-up succeeded. A failure midway keeps what was
// finished (checkpoint.json, metrics.csv, estimate.exr, each written on its own) and throws
// std::runtime_error "<cause>; the run stopped at epoch E and its ... are in DIR".
// Split over ranks (options.communicator): rank 0 alone writes `dir` (the references and final
// renders gathered from their ranks, one observation at a time) and shows progress; every rank
// returns the same result; errors in the set-up and in rank 0's writes are agreed
// (run_agreed: RankFailed on every rank).
InversionDirectoryResult run_inversion_in_directory(const InversionOptions& options, const std::string& dir,
                                                    const InversionDirectoryControl& control = {});

// Continues the run in `dir` with the options of its run.json, to `epochs` when given (not
// below the checkpoint's epoch; stored in run.json for a later resume), with max_memory_gb.
// Throws std::runtime_error "DIR/run.json: cannot open; ..." / "...: corrupt (...)" /
// "DIR/checkpoint.json: missing; nothing to resume", and load_checkpoint's errors for a
// checkpoint of another run, before anything in `dir` changes. Split over ranks
// (control.communicator): every rank reads run.json and checkpoint.json (`dir` must be visible
// to all of them, e.g. on one machine or a shared file system), rank 0 writes.
InversionDirectoryResult resume_inversion_in_directory(const std::string& dir, std::optional<int> epochs,
                                                       double max_memory_gb,
                                                       const InversionDirectoryControl& control = {});

}  // namespace wavebrdf
