"""hmdem: hydro-mechanical pore-network models for fluids in granular media, on top of YADE.

Layers (see README): ``hmdem.network`` (geometry, no YADE), ``hmdem.flow`` (solvers, no YADE),
``hmdem.dem`` (the only package that imports YADE), cases and CLIs (``hmdem.hele_shaw``).
"""

__version__ = "0.1.0"

import os as _os

# numpy's OpenBLAS would start a thread per core in every process, spinning between the many
# small BLAS calls of a run; two runs side by side (a sweep, two benchmark cases) then
# oversubscribed the 2 cores and a coupled B3 run took 2.5x longer (BENCHMARKS.md). One BLAS
# thread per process costs nothing alone (vf: 4.6 s either way). Set before numpy is imported;
# the user's own setting wins.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
