"""Layer 0, kernels: pure functions on arrays that know nothing of the environment.

``geometry`` (segments, discs, frames), ``contacts`` (swept disc-vs-wall and disc-vs-disc),
``planner`` (SocialGym 2.0's arc-sampling local planner and route progress), ``orca``
(ORCA half-planes and their linear program), ``zone_books`` (conflict-zone bookkeeping).
The other kernel packages sit beside this one: ``sgjax.maps``, ``sgjax.dynamics``,
``sgjax.humans``.
"""
