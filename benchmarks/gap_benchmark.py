"""Withheld-effect benchmark of the sim-to-real diagnosis (same as ``grader bench-gap``).

    python benchmarks/gap_benchmark.py --n 10 --seed 0 [--sweep] [--effects a,b] [--workdir DIR]

See :mod:`grader.gap.bench` for the protocol and the magnitude ranges.
"""

from __future__ import annotations

import sys

from grader.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench-gap", *sys.argv[1:]]))
