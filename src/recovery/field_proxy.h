#pragma once
// The field stage for GHS-type observations (experiments/2026-11-23-oblique-light-and-models.md).
//
// A GHS (RGHS) slice scales the Gabor kernels' phase and frequency by s = C3/2 =
// (cos θ_i + cos θ_o)/2 per pixel; at constant s it is exactly the OHS (ROHS) slice of the
// heights s·H (the same c1). Near the specular direction, where a slice's energy is, s is
// cos θ_i: the field stage runs on the separable proxy (the same slices, model OHS / ROHS) for
// the heights cos θ_i · H, its heights are divided by cos θ_i, and the refinement in the full
// model finishes.
#include <map>
#include <vector>

#include "wavebrdf/communicator.h"
#include "wavebrdf/model.h"
#include "wavebrdf/observation.h"

namespace wavebrdf::detail {

// Whether single-wavelength observations of `model` feed the field stage: OHS and ROHS
// directly, GHS and RGHS through their separable proxy; not Kirchhoff.
bool has_field_stage(Model model);

// The separable model whose slice of the heights s·H stands for `model`'s slice of H: OHS for
// OHS and GHS, ROHS for ROHS and RGHS. Throws std::invalid_argument for Kirchhoff.
Model field_proxy_model(Model model);

// The height scale s of the proxy (dimensionless, in (0, 1]): cos θ_i = sqrt(1 − |ω_i|²) for
// GHS and RGHS (C3/2 at the specular direction), 1 for OHS and ROHS.
double field_height_scale(const Query& query);

// The field stage's proxy for every rank's field-stage observations (collective: call on every
// rank): `height_scale` their one height scale (1 when there are none), `proxied` whether any
// of them is GHS or RGHS. Throws std::invalid_argument naming the two scales when they differ by
// more than 1e-12 (GHS slices under different light directions, or GHS mixed with OHS under
// oblique light: no single proxy).
struct FieldProxy {
    double height_scale = 1.0;
    bool proxied = false;
};
FieldProxy common_field_proxy(const std::map<double, std::vector<const Observation*>>& by_lambda,
                              const Communicator& comm);

}  // namespace wavebrdf::detail
