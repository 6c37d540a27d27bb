#!/usr/bin/env python3
"""The thesis's listing 4.1 ("Simplified Python code for the overall procedure") in wavebrdf's
Python API: render a reference slice of a true heightfield, start from a flat hypothesis, and
move its heights along the gradient of the loss, epoch by epoch.

    PYTHONPATH=build/python /usr/bin/python3 examples/listing_4_1.py [--epochs 300] [--stochastic]

Defaults are the thesis's first experiment: a 16x16 surface, normal incidence, sigma_p = 4 um,
a 32x32 slice of 8 wavelengths in linear sRGB, CMSLE (epsilon 1), Adam (0.01, 0.9, 0.99) with
decay 0.005 per epoch. `wavebrdf invert` (and wavebrdf.invert) run the same loop in C++.
"""
import argparse
import sys

import numpy as np

import wavebrdf as wb


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--truth", help="true heightfield EXR (default: a generated 16x16 surface)")
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--resolution", type=int, default=32)
    parser.add_argument("--stochastic", action="store_true", help="a new random footprint position every epoch")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)

    # Generate reference
    if args.truth:
        gr_truth_hf = wb.Heightfield.from_exr(args.truth)
    else:  # heights of about +-1 texel, like the thesis's crop of the release's isotropic.exr
        gr_truth_hf = wb.Heightfield.generate("isotropic", rows=16, rms_height_um=0.35, correlation_um=2.0,
                                              seed=args.seed)
    query = wb.Query(x_um=gr_truth_hf.period_x_um / 2, y_um=gr_truth_hf.period_y_um / 2, sigma_p_um=4.0,
                     spectral=8)
    gr_truth_gabor = wb.GaborRep(gr_truth_hf, query)  # the kernels within the footprint
    # rounded to float32, as a wb.Observation (and so wb.invert) holds a reference
    ref_brdf = wb.render(gr_truth_gabor, query, resolution=args.resolution).astype(np.float32).astype(np.float64)

    # Initialize hypothesis: a plane at height zero
    hypo_hf = wb.Heightfield(np.zeros(gr_truth_hf.shape), gr_truth_hf.texel_um, gr_truth_hf.vscale)
    loss_fn = wb.Loss("cmsle:1")
    optimizer = wb.Adam(hypo_hf.rows * hypo_hf.cols, lr=0.01, beta1=0.9, beta2=0.99, decay=0.005)
    rng = np.random.default_rng(args.seed)

    # Optimize
    losses = []
    for epoch in range(args.epochs + 1):
        epoch_query = query
        if args.stochastic:  # the reference of a random footprint position
            epoch_query = query.copy()
            epoch_query.x_um, epoch_query.y_um = rng.uniform(0.0, 1.0, 2) * (gr_truth_hf.period_x_um,
                                                                               gr_truth_hf.period_y_um)
            ref_brdf = wb.render(wb.GaborRep(gr_truth_hf, epoch_query), epoch_query,
                                 resolution=args.resolution).astype(np.float32).astype(np.float64)
        brdf = wb.render(hypo_hf, epoch_query, resolution=args.resolution)
        loss, dloss_dbrdf = loss_fn.value_and_gradient(brdf, ref_brdf)
        grad = wb.gradient(hypo_hf, epoch_query, dloss_dbrdf)  # backward(loss): the adjoint, d loss / d heights
        losses.append(loss)
        if not args.quiet and (epoch % 50 == 0 or epoch == args.epochs):
            print("epoch %4d  loss %.6g" % (epoch, loss))
        if epoch == args.epochs:
            break
        values = hypo_hf.to_numpy()
        optimizer.step(values, grad, epoch)  # in place
        hypo_hf.values = values

    height_mse = wb.height_mse(hypo_hf.heights_um(), gr_truth_hf.heights_um())
    flat_mse = wb.height_mse(np.zeros(gr_truth_hf.shape), gr_truth_hf.heights_um())
    print("final: loss %.6g (%.2f%% of epoch 0), height MSE %.4g um^2 (flat start: %.4g)"
          % (losses[-1], 100.0 * losses[-1] / losses[0], height_mse, flat_mse))
    return {"losses": np.array(losses), "estimate": hypo_hf, "truth": gr_truth_hf, "reference": ref_brdf}


if __name__ == "__main__":
    main(sys.argv[1:])
