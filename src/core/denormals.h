#pragma once
// Internal: single-precision products whose operands fall below FLT_MIN (1.2e-38) — the
// Gaussian envelopes e^{−2π²σ²u²} of a kernel far out in u, a narrow blur's tails — run in the
// CPU's microcoded denormal path. On the Intel Xeon of the 2-core machine a 48 × 64 × 48 complex
// float product with 130 denormal inputs took 30× longer (≈ 570 µs instead of ≈ 18 µs), which
// made the refinement and the blurred fit spend most of their time in Eigen's GEMM kernel
// (experiments/2026-11-23-recovery-speed.md). FlushDenormals sets the calling thread's
// flush-to-zero and denormals-are-zero modes while it lives and puts the caller's two modes
// back afterwards: values below FLT_MIN (DBL_MIN in double arithmetic) count as 0, far below
// anything a slice resolves. Only the calling thread changes: a scope that spreads its work
// over a nested team must set it in each thread. No-op where the target has no SSE control
// register.
#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

namespace wavebrdf::detail {

class FlushDenormals {
public:
#if defined(__SSE2__)
    static constexpr unsigned k_bits = 0x8040u;  // MXCSR: flush to zero (bit 15), denormals are zero (bit 6)
    FlushDenormals() : m_saved(_mm_getcsr()) { _mm_setcsr(m_saved | k_bits); }
    ~FlushDenormals() { _mm_setcsr((_mm_getcsr() & ~k_bits) | (m_saved & k_bits)); }

private:
    unsigned m_saved;
#else
    FlushDenormals() = default;
#endif
public:
    FlushDenormals(const FlushDenormals&) = delete;
    FlushDenormals& operator=(const FlushDenormals&) = delete;
};

}  // namespace wavebrdf::detail
