"""Statistics over evaluation episodes, and the result record of one configuration.

Every metric is summarised over the episodes that have a value: the mean, a 95% confidence
interval (Wilson score for yes/no episode metrics, Student t of the mean for the rest, clipped
to the metric's range), the standard deviation and the count. :class:`ConfigResult` holds the
summaries of one scenario x policy x robot count; :mod:`sgjax.evaluation.evaluate` produces them and
:mod:`sgjax.evaluation.report` writes them.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sgjax.evaluation.metrics import METRICS

CONFIDENCE = 0.95


@dataclasses.dataclass(frozen=True)
class Summary:
    """Mean of a metric over the episodes that have a value, with its 95% interval."""

    mean: float
    ci_low: float
    ci_high: float
    std: float
    n: int

    def as_dict(self) -> dict[str, float | int | None]:
        def clean(v: float) -> float | None:
            return None if math.isnan(v) else float(v)
        return {"mean": clean(self.mean), "ci_low": clean(self.ci_low),
                "ci_high": clean(self.ci_high), "std": clean(self.std), "n": self.n}


def _scipy_stats() -> Any:
    """``scipy.stats``, imported at first use: it costs a third of a second, which every
    command would otherwise pay at start-up whether it reports intervals or not."""
    from scipy import stats

    return stats


def wilson_interval(successes: float, n: int, confidence: float = CONFIDENCE
                    ) -> tuple[float, float]:
    """Wilson score interval of a proportion ``successes / n``."""
    if n == 0:
        return math.nan, math.nan
    z = float(_scipy_stats().norm.ppf(0.5 + confidence / 2))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def t_interval(values: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Student-t interval of the mean of ``values`` (NaN with fewer than two)."""
    n = len(values)
    if n < 2:
        return math.nan, math.nan
    mean = float(np.mean(values))
    half = float(_scipy_stats().t.ppf(0.5 + confidence / 2, n - 1)) * float(
        np.std(values, ddof=1)) / math.sqrt(n)
    return mean - half, mean + half


def paired_difference(a: np.ndarray, b: np.ndarray, confidence: float = CONFIDENCE) -> Summary:
    """``a - b`` over paired episodes (the same episode played by two policies: common random
    numbers), ``[E]`` each: the mean difference with its Student-t interval over the
    per-episode differences. Pairs where either value is NaN are left out; an interval that
    excludes 0 is what "A beats B" needs."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        raise ValueError(f"paired_difference: {a.shape} and {b.shape} episodes do not pair")
    diff = (a - b)[np.isfinite(a) & np.isfinite(b)]
    if not diff.size:
        return Summary(math.nan, math.nan, math.nan, math.nan, 0)
    low, high = t_interval(diff, confidence)
    std = float(np.std(diff, ddof=1)) if diff.size > 1 else math.nan
    return Summary(float(np.mean(diff)), low, high, std, int(diff.size))


def probability_of_improvement(a: np.ndarray, b: np.ndarray) -> float:
    """P(A > B) for one run of each drawn at random: the share of pairs ``(a_i, b_j)`` with
    ``a_i > b_j``, ties counting half (rliable's probability of improvement, the Mann-Whitney
    U statistic over ``len(a) * len(b)``); NaN values left out, NaN if either side is empty."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(_improvement(a[None, np.isfinite(a)], b[None, np.isfinite(b)])[0])


def interquartile_mean(values: np.ndarray, axis: int | None = None) -> float | np.ndarray:
    """Mean of the middle half of ``values`` (25% trimmed from each end: rliable's IQM, robust
    to one outlying seed and less noisy than the median); NaN for no values. With ``axis``,
    the IQM along that axis of an array (one per row: the bootstrap's resamples at once)."""
    values = np.asarray(values, float)
    if axis is not None:
        return _scipy_stats().trim_mean(values, 0.25, axis=axis)
    return float(_scipy_stats().trim_mean(values, 0.25)) if values.size else math.nan


def seed_aggregate(per_seed: np.ndarray, confidence: float = CONFIDENCE, resamples: int = 2000,
                   seed: int = 0) -> dict[str, float]:
    """Aggregate of one cell over training seeds (``per_seed [S]``, each seed's mean over its
    episodes), in the rliable methodology: the mean and the interquartile mean, each with a
    percentile-bootstrap interval over seeds (``resamples`` resamples, fixed ``seed``; with one
    cell, the stratified bootstrap is the plain one). Computed with scipy rather than the
    rliable package, which pulls statsmodels, arch and formulaic in for these few lines. With
    fewer than two seeds the intervals are NaN."""
    values = np.asarray(per_seed, float)
    values = values[np.isfinite(values)]
    out = {"seeds": int(values.size), "mean": float(np.mean(values)) if values.size else math.nan,
           "iqm": interquartile_mean(values)}
    for name, statistic in (("mean", np.mean), ("iqm", interquartile_mean)):
        low = high = math.nan
        if values.size > 1 and np.ptp(values) > 0:
            result = _scipy_stats().bootstrap(
                (values,), lambda v, axis=-1, f=statistic: f(v, axis=axis),
                confidence_level=confidence, n_resamples=resamples, method="percentile",
                random_state=np.random.default_rng(seed))
            low, high = (float(result.confidence_interval.low),
                         float(result.confidence_interval.high))
        elif values.size > 1:  # every seed the same: no spread to resample
            low = high = float(values[0])
        out[f"{name}_low"], out[f"{name}_high"] = low, high
    return out


def paired_over_seeds_and_episodes(a: np.ndarray, b: np.ndarray,
                                   confidence: float = CONFIDENCE, resamples: int = 4000,
                                   seed: int = 0) -> Summary:
    """``A - B`` where A is trained over seeds and both play the same episodes: ``a [S, E]``
    (each training seed's value on each shared episode), ``b [E]`` or ``[S, E]`` (an untrained
    baseline's values on the same episodes, or another trained policy's, seed by seed). The
    mean difference with a **two-level bootstrap** interval: each resample draws ``S`` seeds
    with replacement, then ``E`` episodes with replacement (the same episodes for A and B:
    paired), so the interval carries the variance of training seeds and of episodes together
    (a t interval over episodes of seed-averaged differences carries the episodes' alone).
    Percentile interval over ``resamples`` resamples (fixed ``seed``); ``n`` is ``S x E``.
    NaN pairs are left out of each mean."""
    a = np.asarray(a, float)
    b = np.broadcast_to(np.asarray(b, float), a.shape)
    if a.ndim != 2:
        raise ValueError(f"paired_over_seeds_and_episodes: a must be [seeds, episodes], got "
                         f"{a.shape}")
    diff = a - b
    seeds, episodes = diff.shape
    if not np.isfinite(diff).any():
        return Summary(math.nan, math.nan, math.nan, math.nan, 0)
    means = _two_level_means(diff, np.random.default_rng(seed), resamples)
    tail = (1 - confidence) / 2
    low, high = np.nanquantile(means, [tail, 1 - tail])
    finite = diff[np.isfinite(diff)]
    return Summary(float(np.mean(finite)), float(low), float(high),
                   float(np.std(finite, ddof=1)) if finite.size > 1 else math.nan,
                   int(finite.size))


def _two_level_means(diff: np.ndarray, rng: np.random.Generator, resamples: int
                     ) -> np.ndarray:
    """``[resamples]`` NaN-aware means of two-level resamples of ``diff [S, E]``: resample
    ``r`` picks ``S`` rows, then ``E`` columns, with replacement (the draws of a loop of
    ``rng.integers(0, S, S)``, ``rng.integers(0, E, E)`` per resample, made in one call:
    numpy gives the same numbers either way), and its mean over the picked block is the
    count-weighted sum ``(n_rows @ values @ n_cols) / (n_rows @ finite @ n_cols)`` (NaN where
    the block holds no finite value)."""
    seeds, episodes = diff.shape
    highs = np.concatenate([np.full(seeds, seeds), np.full(episodes, episodes)])
    picks = rng.integers(0, np.tile(highs, resamples)).reshape(resamples, highs.size)
    rows = _pick_counts(picks[:, :seeds], seeds)  # [R, S] how often each seed was drawn
    cols = _pick_counts(picks[:, seeds:], episodes)  # [R, E]
    finite = np.isfinite(diff)
    total = np.einsum("rs,se,re->r", rows, np.where(finite, diff, 0.0), cols)
    count = np.einsum("rs,se,re->r", rows, finite.astype(float), cols)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1.0), np.nan)


def _pick_counts(picks: np.ndarray, size: int) -> np.ndarray:
    """``[R, size]`` counts of each index in every row of ``picks [R, n]``."""
    rows = picks.shape[0]
    flat = (picks + size * np.arange(rows)[:, None]).ravel()  # row r's indices shifted by r x size
    return np.bincount(flat, minlength=rows * size).reshape(rows, size).astype(float)


def per_seed_paired_t(a: np.ndarray, b: np.ndarray, confidence: float = CONFIDENCE
                      ) -> Summary:
    """``A - B`` as a Student-t interval over training seeds of each seed's paired
    difference (its mean over the shared episodes): ``a [S, E]``, ``b [E]`` or ``[S, E]``.
    The other interval :func:`paired_over_seeds_and_episodes` offers: exact under normal
    seed means, and with few seeds wide, as it should be (never the range of the seeds)."""
    a = np.asarray(a, float)
    b = np.broadcast_to(np.asarray(b, float), a.shape)
    per_seed = np.nanmean(a - b, axis=1)
    per_seed = per_seed[np.isfinite(per_seed)]
    if not per_seed.size:
        return Summary(math.nan, math.nan, math.nan, math.nan, 0)
    low, high = t_interval(per_seed, confidence)
    return Summary(float(np.mean(per_seed)), low, high,
                   float(np.std(per_seed, ddof=1)) if per_seed.size > 1 else math.nan,
                   int(per_seed.size))


def stratified_resamples(cells: Mapping[str, np.ndarray], resamples: int, seed: int
                         ) -> np.ndarray:
    """``resamples`` stratified bootstrap resamples of per-seed scores by cell (``cells
    {cell: [S_c]}``), ``[resamples, runs]``: each row draws every cell's finite seeds with
    replacement within the cell, the cells side by side in their order (rliable's stratified
    bootstrap)."""
    if not any(np.isfinite(np.asarray(v, float)).any() for v in cells.values()):
        raise ValueError(f"no finite score in any of the {len(cells)} cells to resample")
    (drawn,) = _draws([_finite(cells)], np.random.default_rng(seed), resamples)
    return np.concatenate(list(drawn.values()), axis=1)


def _finite(cells: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Every cell's finite scores, as float arrays."""
    out = {}
    for cell, values in cells.items():
        v = np.asarray(values, float)
        out[cell] = v[np.isfinite(v)]
    return out


def _draws(groups: Sequence[Mapping[str, np.ndarray]], rng: np.random.Generator,
           resamples: int) -> list[dict[str, np.ndarray]]:
    """``resamples`` stratified draws of every group of cells (each cell already reduced to
    its finite scores): per group, ``{cell: [resamples, S_c]}``. One call of the generator
    draws them all, in the order of a loop over resamples, then groups, then cells, each
    ``rng.integers(0, S_c, S_c)`` (numpy gives the same numbers either way), so a resample
    is what one :func:`resample_cells` per group gives."""
    layout = [(g, cell, v) for g, group in enumerate(groups) for cell, v in group.items()]
    sizes = np.asarray([v.size for *_, v in layout], np.int64)
    highs = np.repeat(sizes, sizes)
    picks = rng.integers(0, np.tile(highs, resamples)).reshape(resamples, highs.size)
    out: list[dict[str, np.ndarray]] = [{} for _ in groups]
    start = 0
    for (g, cell, v), size in zip(layout, sizes, strict=True):
        out[g][cell] = v[picks[:, start:start + size]]
        start += size
    return out


def resample_cells(cells: Mapping[str, np.ndarray], rng: np.random.Generator
                   ) -> dict[str, np.ndarray]:
    """Every cell's finite scores drawn with replacement within the cell (one stratified
    bootstrap draw; a cell without finite scores stays empty)."""
    (drawn,) = _draws([_finite(cells)], rng, 1)
    return {cell: v[0] for cell, v in drawn.items()}


def aggregate_over_cells(cells: Mapping[str, np.ndarray], confidence: float = CONFIDENCE,
                         resamples: int = 2000, seed: int = 0) -> dict[str, float]:
    """One method's aggregate over all its cells (``cells {cell: [S] per-seed scores}``, e.g.
    every scenario x robot count): the interquartile mean and the mean of every run, each with
    a stratified-bootstrap percentile interval (seeds resampled within each cell)."""
    everything = np.concatenate([np.asarray(v, float) for v in cells.values()])
    everything = everything[np.isfinite(everything)]
    out = {"runs": int(everything.size), "cells": len(cells),
           "iqm": interquartile_mean(everything),
           "mean": float(np.mean(everything)) if everything.size else math.nan}
    draws = stratified_resamples(cells, resamples, seed)
    tail = (1 - confidence) / 2
    for name, values in (("iqm", interquartile_mean(draws, axis=1)),
                         ("mean", np.mean(draws, axis=1))):
        out[f"{name}_low"], out[f"{name}_high"] = (float(q) for q in np.quantile(
            values, [tail, 1 - tail]))
    return out


def _improvement(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """P(A > B) of every row at once (:func:`probability_of_improvement`, and every bootstrap
    resample): ``a [R, S_a]``, ``b [R, S_b]`` finite scores -> ``[R]`` (NaN where a side is
    empty)."""
    if a.shape[1] == 0 or b.shape[1] == 0:
        return np.full(a.shape[0], math.nan)
    above = (a[:, :, None] > b[:, None, :]) + 0.5 * (a[:, :, None] == b[:, None, :])
    return np.mean(above.reshape(a.shape[0], -1), axis=1)


def improvement_over_cells(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray],
                           confidence: float = CONFIDENCE, resamples: int = 2000,
                           seed: int = 0) -> dict[str, float]:
    """P(A > B) over the cells both have (the mean over cells of each cell's
    :func:`probability_of_improvement` of its seeds), with a stratified-bootstrap percentile
    interval (each side's seeds resampled within each cell)."""
    shared = [c for c in a if c in b]
    if not shared:
        raise ValueError("improvement_over_cells: no cell in common")
    value = float(np.nanmean([probability_of_improvement(a[c], b[c]) for c in shared]))
    a_drawn, b_drawn = _draws([_finite({c: a[c] for c in shared}),
                               _finite({c: b[c] for c in shared})],
                              np.random.default_rng(seed), resamples)
    by_cell = np.stack([_improvement(a_drawn[c], b_drawn[c]) for c in shared], axis=1)
    with warnings.catch_warnings():  # a resample whose every cell is empty: NaN, left out
        warnings.simplefilter("ignore", RuntimeWarning)
        values = np.nanmean(by_cell, axis=1)
    tail = (1 - confidence) / 2
    low, high = np.nanquantile(values, [tail, 1 - tail])
    return {"probability": value, "low": float(low), "high": float(high),
            "cells": len(shared)}


def performance_profile(cells: Mapping[str, np.ndarray], thresholds: np.ndarray,
                        confidence: float = CONFIDENCE, resamples: int = 2000, seed: int = 0
                        ) -> dict[str, np.ndarray]:
    """The fraction of a method's runs (seeds of every cell) whose score exceeds each threshold
    (``thresholds [T]``), with a stratified-bootstrap percentile band: ``{"thresholds",
    "fraction", "low", "high"}`` (rliable's performance profile)."""
    thresholds = np.asarray(thresholds, float)
    everything = np.concatenate([np.asarray(v, float) for v in cells.values()])
    everything = everything[np.isfinite(everything)]
    fraction = np.mean(everything[:, None] > thresholds[None], axis=0)
    drawn = stratified_resamples(cells, resamples, seed)
    draws = np.mean(drawn[:, :, None] > thresholds[None, None], axis=1)
    tail = (1 - confidence) / 2
    return {"thresholds": thresholds, "fraction": fraction,
            "low": np.quantile(draws, tail, axis=0), "high": np.quantile(draws, 1 - tail, axis=0)}


def summarize(values: np.ndarray, binary: bool, fraction: bool = False) -> Summary:
    """Summary over episodes of one metric's per-episode values (NaNs are left out). Every
    metric is non-negative, so the interval is clipped at 0, and at 1 for ``fraction``s."""
    x = np.asarray(values, np.float64)
    x = x[np.isfinite(x)]
    n = len(x)
    if n == 0:
        return Summary(math.nan, math.nan, math.nan, math.nan, 0)
    low, high = wilson_interval(float(np.sum(x)), n) if binary else t_interval(x)
    low, high = max(low, 0.0), (min(high, 1.0) if fraction else high)
    std = float(np.std(x, ddof=1)) if n > 1 else math.nan
    return Summary(float(np.mean(x)), low, high, std, n)


def summarize_metrics(values: Mapping[str, np.ndarray]) -> dict[str, Summary]:
    """:func:`summarize` of every registered metric's per-episode values ``{name: [E]}``, in
    catalogue order (:data:`sgjax.evaluation.metrics.METRICS`), with each metric's interval
    kind and range."""
    return {info.name: summarize(values[info.name], info.binary, info.unit == "fraction")
            for info in METRICS}


@dataclasses.dataclass
class ConfigResult:
    """One configuration's summaries (``metrics`` in the catalogue order of
    :data:`sgjax.evaluation.metrics.METRICS`)."""

    scenario: str
    policy: str
    num_agents: int
    episodes: int
    seed: int
    dt: float
    max_steps: int
    metrics: dict[str, Summary]
    seconds: float  # wall time, compile included
    compile_seconds: float | None = None  # compiling the batched run
    run_seconds: float | None = None  # running it, once compiled
    counterfactual: bool = False  # the counterfactual lanes ran (their metrics are filled in)
    steps_played: int | None = None  # steps the batch ran before every episode had ended
    # the sgjax.make options the configuration was played in (MakeOptions.to_dict: every
    # option by group), so that a result file says which constants, observations and robots
    options: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in dataclasses.asdict(self).items() if k != "metrics"}
        out["metrics"] = {name: s.as_dict() for name, s in self.metrics.items()}
        return out

    @property
    def agent_steps_per_second(self) -> float | None:
        """Robot-steps simulated per second once compiled, when timed: every episode of the
        batch steps (frozen after its end) until the last one has ended, ``steps_played``
        (the time limit when not given); counterfactual lanes are not counted."""
        if not self.run_seconds:
            return None
        steps = self.max_steps if self.steps_played is None else self.steps_played
        return self.episodes * steps * self.num_agents / self.run_seconds
