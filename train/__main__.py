"""``python -m train --config train/configs/doorway.yaml``."""

from train.cli import main

main()
