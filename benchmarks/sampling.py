"""How evenly `riverbench sweep --sample N` covers the sampled keys' box with each --sampler: the centred L2
discrepancy (scipy.stats.qmc.discrepancy, method CD; lower is more even) of the sweep's own unit samples.

    python benchmarks/sampling.py [--n 64] [--dims 3] [--seeds 20]

Prints, per sampler, the median (and min..max) over sample seeds 0..seeds-1, and the ratio to plain random
draws, which is what `--sample` used before the Latin hypercube became its default.
"""

from __future__ import annotations

import argparse
import statistics

from scipy.stats import qmc

from scenarios.batch.plan import SAMPLERS, unit_samples


def discrepancies(sampler: str, n: int, dims: int, seeds: int) -> list[float]:
    """Centred L2 discrepancy of the sweep's unit samples for each sample seed."""
    return [float(qmc.discrepancy(unit_samples(sampler, n, dims, seed), method="CD")) for seed in range(seeds)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=64, help="samples (a power of 2, for Sobol')")
    parser.add_argument("--dims", type=int, default=3, help="sampled keys")
    parser.add_argument("--seeds", type=int, default=20, help="sample seeds to take the median over")
    args = parser.parse_args()
    values = {s: discrepancies(s, args.n, args.dims, args.seeds) for s in SAMPLERS}
    random = statistics.median(values["random"])
    print(f"centred L2 discrepancy of {args.n} samples in {args.dims}-D, over sample seeds 0..{args.seeds - 1} (lower: more even)")
    print(f"{'sampler':<8} {'median':>10} {'min':>10} {'max':>10} {'x random':>9}")
    for sampler in ("random", "lhs", "sobol"):
        v = values[sampler]
        print(f"{sampler:<8} {statistics.median(v):>10.5f} {min(v):>10.5f} {max(v):>10.5f} {statistics.median(v) / random:>9.2f}")


if __name__ == "__main__":
    main()
