#pragma once
// One slice's amplitude loss on its operator's pixel box and its gradient with respect to the
// slice's field: the per-pixel terms of retrieve_field (recover_field.cpp) and of FieldModelLoss
// (recover_field_model.cpp), written once.

#include <Eigen/Core>
#include <cmath>
#include <complex>

namespace wavebrdf::detail {

// Over the box's pixels (a, b), the model amplitude m = c(a, b) |Ψ(a, b)| against √R(a, b),
// each counted with its pixel weight w(a, b) (Observation::weights; UnitWeight without them);
// a pixel with c = 0 (outside the disk) has no model value: it adds w R and gets no gradient:
//   L = outside + Σ_{c≠0} w (s m − √R)² + Σ_{c=0} w R
// (`outside`: Σ w R beyond the box, the sum's start). A pixel of weight 0 enters nothing (its
// √R is never used). s = 1, or with `calibrate_exposure` the self-calibrated exposure
// s = √(Σ_{c≠0} w R / Σ w m²) (calibration_detail.h: the ratio of the energies over the
// weighted pixels; 1 when the model is all 0 there), differentiated too: with
// C = Σ w (s m − √R) m, ∂L/∂|Ψ_k| gains −2 C s w_k c_k² |Ψ_k| / Σ w m².
// Returns L; g (resized to psi's shape) receives gradient_scale · (∂L/∂Re Ψ + i ∂L/∂Im Ψ),
// 0 where |Ψ| = 0, c = 0 or w = 0. `amp`, `sqrt_ref` and `weight` are read as amp(a, b),
// sqrt_ref(a, b), weight(a, b) (Eigen matrices or accessors); the sums are in double whatever
// the field's scalar. UnitWeight: every pixel weight 1 (an observation without weights).
struct UnitWeight {
    float operator()(Eigen::Index, Eigen::Index) const { return 1.0f; }
};

template <typename Scalar, typename Amplitude, typename SqrtReference, typename Weight>
double amplitude_box_loss(const Eigen::Matrix<std::complex<Scalar>, Eigen::Dynamic, Eigen::Dynamic>& psi,
                          const Amplitude& amp, const SqrtReference& sqrt_ref, const Weight& weight, double outside,
                          bool calibrate_exposure, double gradient_scale,
                          Eigen::Matrix<std::complex<Scalar>, Eigen::Dynamic, Eigen::Dynamic>& g) {
    g.resize(psi.rows(), psi.cols());
    double v = outside, root_exposure = 1.0, model_total = 0.0;
    if (calibrate_exposure) {
        double reference_total = 0.0;
        for (Eigen::Index b = 0; b < psi.cols(); ++b)
            for (Eigen::Index a = 0; a < psi.rows(); ++a) {
                const double c = double(amp(a, b)), w = double(weight(a, b));
                if (c == 0.0 || w == 0.0) continue;
                const double re = double(psi(a, b).real()), im = double(psi(a, b).imag());
                model_total += w * (c * c * (re * re + im * im));
                const double r = double(sqrt_ref(a, b));
                reference_total += w * (r * r);
            }
        if (model_total > 0.0) root_exposure = std::sqrt(reference_total / model_total);
    }
    double cross = 0.0;
    for (Eigen::Index b = 0; b < psi.cols(); ++b)
        for (Eigen::Index a = 0; a < psi.rows(); ++a) {
            const double c = double(amp(a, b)), w = double(weight(a, b));
            if (w == 0.0) {  // out of the loss: its reference is not read
                g(a, b) = Scalar(0);
                continue;
            }
            if (c == 0.0) {  // outside the disk: no model value, no gradient
                const double r = double(sqrt_ref(a, b));
                v += w * (r * r);
                g(a, b) = Scalar(0);
                continue;
            }
            // |Ψ| as √(re² + im²): std::abs calls hypot, ~5× slower, and Ψ is far from its
            // overflow / underflow range.
            const double re = double(psi(a, b).real()), im = double(psi(a, b).imag());
            const double mag = std::sqrt(re * re + im * im);
            const double diff = root_exposure * c * mag - double(sqrt_ref(a, b));
            v += w * (diff * diff);
            cross += w * (diff * c * mag);
            g(a, b) = mag > 0.0 ? Scalar(2.0 * gradient_scale * w * diff * root_exposure * c / mag) * psi(a, b)
                                : std::complex<Scalar>(Scalar(0));
        }
    if (calibrate_exposure && model_total > 0.0) {
        const double shift = 2.0 * gradient_scale * cross * root_exposure / model_total;
        for (Eigen::Index b = 0; b < psi.cols(); ++b)
            for (Eigen::Index a = 0; a < psi.rows(); ++a) {
                const double c = double(amp(a, b)), w = double(weight(a, b));
                if (c != 0.0) g(a, b) -= Scalar(shift * w * c * c) * psi(a, b);
            }
    }
    return v;
}

}  // namespace wavebrdf::detail
