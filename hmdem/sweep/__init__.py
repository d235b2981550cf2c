"""Parameter sweeps of the linear Hele-Shaw model: the Lenormand phase diagram (issue 4).

``python -m hmdem.sweep lenormand`` runs ``python -m hmdem.hele_shaw linear`` over a grid of
viscosity ratio M and modified capillary number Ca* (seed 004 Eq. 24) with replicate seeds,
on an embedded Dask LocalCluster or an existing Dask scheduler; every run keeps its own run
directory. ``python -m hmdem.sweep collect DIR`` aggregates any directory of run directories
(ours or a ``yade-batch`` job's) into ``sweep.csv`` and ``phase_diagram.png``.

Modules: :mod:`.grid` (the points), :mod:`.runner` (one point), :mod:`.manifest` (resume
bookkeeping), :mod:`.execute` (Dask), :mod:`.table` (sweep.csv), :mod:`.phase_diagram`.
"""
