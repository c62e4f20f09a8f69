"""Layer 0, kernels: pure functions on arrays that know nothing of the environment.

``geometry`` (segments, discs, frames), ``contacts`` (swept disc-vs-wall and disc-vs-disc),
``orca`` (ORCA half-planes and their linear program), ``zone_books`` (conflict-zone
bookkeeping), ``row_chunks`` (work on a batch's flagged rows, a chunk at a time). The other
packages of the layer sit above this one, in this order: ``sgjax.maps``, ``sgjax.dynamics``
(with the local planner), ``sgjax.humans``.
"""
