#!/usr/bin/python3
"""One line per design.json: exact region mean/worst, uniformity worst (at λ), cone worst, relaxed."""
import json, sys
for path in sys.argv[1:]:
    j = json.load(open(path))
    e = j["metrics"]["exact"]; r = j["metrics"].get("relaxed") or {}
    lam = j["light"]["lambdas_um"]
    iu = max(range(len(e["uniformity"])), key=lambda i: e["uniformity"][i])
    print(f"{path}: region {100*e['region_fraction_mean']:.1f}% (worst {100*e['region_fraction_worst']:.1f}%) "
          f"unif worst {e['uniformity_worst']:.3f} @{lam[iu]:.3f} mean {e['uniformity_mean']:.3f} "
          f"cone worst {100*e['specular_fraction_worst']:.3f}% | relaxed region "
          f"{100*r.get('region_fraction_mean', 0):.1f}% unif {r.get('uniformity_worst', 0):.3f} "
          f"t {j['timings_s']['total']:.0f}s")
