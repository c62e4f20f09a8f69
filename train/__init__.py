"""The JAX IPPO / MAPPO trainer for sgjax: ``python -m train --config train/configs/doorway.yaml``
(see ``docs/training.md``)."""
