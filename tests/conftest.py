"""Shared test settings: headless matplotlib, deterministic float32 JAX."""

import matplotlib

matplotlib.use("Agg")
