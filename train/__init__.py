"""The JAX IPPO / MAPPO trainer for sgjax: ``python -m train --config train/configs/doorway.yaml``
(see ``docs/training.md``).

Its wings, lowest first (each imports only itself or lower; tests/contracts/test_architecture.py):

- ``algorithm``: the training config, networks, observation statistics, the actor and PPO;
- ``run``: checkpoints, devices, processes, sweep spaces and SocialGym 2.0 config conversion;
- ``reports``: learning curves, result tables and exports;
- the experiment commands at the top: ``cli`` (``python -m train``, ``sgjax-train``),
  ``reproduce``, ``ablation`` and ``sweep`` (``python -m train.<command>``).
"""
