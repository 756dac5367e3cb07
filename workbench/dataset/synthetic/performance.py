"""A performance: smooth muscle activation curves of an actor going through expressions and speech.

The take is a sequence of events placed one after another with random lengths and overlaps:

- held expressions (FACS-like muscle combinations: smile, surprise, anger, sadness, pucker, ...), each with an
  attack-hold-release envelope, a random intensity and a little left/right asymmetry;
- speech-like segments: the jaw and lip muscles oscillate at syllable rates (3-6 Hz) with varying amplitude;
- single muscles on one side of the face;
- rest periods.

Overlapping events combine as ``1 - prod(1 - c_k)``, which keeps every activation in [0, 1] and lets a single
event reach its own level exactly. The take starts with a second of rest (all activations exactly zero).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.synthetic.muscles import MUSCLE_NAMES, N_MUSCLES


@dataclass(frozen=True)
class Expression:
    """A held facial expression: the activation of each muscle involved at full intensity."""

    name: str
    levels: tuple[tuple[str, float], ...]


def _both(muscle: str, level: float) -> tuple[tuple[str, float], ...]:
    return ((muscle + "_L", level), (muscle + "_R", level))


EXPRESSIONS: tuple[Expression, ...] = (
    Expression("smile", _both("zygomatic_major", 1.0) + _both("risorius", 0.3) + _both("levator_labii", 0.2)),
    Expression("laugh", _both("zygomatic_major", 1.0) + _both("levator_labii", 0.4) + (("jaw_open", 0.45),)),
    Expression("surprise", _both("frontalis_inner", 1.0) + _both("frontalis_outer", 1.0) + (("jaw_open", 0.6),)),
    Expression("brow_raise", _both("frontalis_inner", 0.8) + _both("frontalis_outer", 0.7)),
    Expression(
        "anger", _both("corrugator", 1.0) + _both("levator_labii", 0.3) + (("orbicularis_oris", 0.4), ("mentalis", 0.3))
    ),
    Expression("brow_lower", _both("corrugator", 0.9)),
    Expression(
        "sadness",
        _both("frontalis_inner", 0.8)
        + _both("corrugator", 0.4)
        + _both("depressor_anguli", 0.8)
        + (("mentalis", 0.4),),
    ),
    Expression("pucker", (("orbicularis_oris", 1.0), ("mentalis", 0.3))),
    Expression("jaw_drop", (("jaw_open", 1.0),)),
    Expression("disgust", _both("levator_labii", 1.0) + _both("corrugator", 0.5) + (("depressor_labii", 0.3),)),
    Expression(
        "fear",
        _both("frontalis_inner", 0.8)
        + _both("frontalis_outer", 0.4)
        + _both("corrugator", 0.5)
        + _both("risorius", 0.8)
        + (("jaw_open", 0.3), ("depressor_labii", 0.4)),
    ),
    Expression("grimace", _both("risorius", 1.0) + _both("depressor_anguli", 0.5) + (("depressor_labii", 0.5),)),
    Expression("doubt", (("mentalis", 0.8), ("orbicularis_oris", 0.3)) + _both("depressor_anguli", 0.5)),
    Expression("smirk", (("zygomatic_major_L", 0.7), ("risorius_L", 0.5))),
)


@dataclass(frozen=True)
class PerformanceStyle:
    """Timing and intensity ranges of the events (seconds, activation levels)."""

    lead_rest: float = 1.0
    event_weights: tuple[float, float, float, float] = (0.45, 0.30, 0.15, 0.10)  # expression, speech, single, rest
    attack: tuple[float, float] = (0.15, 0.6)
    hold: tuple[float, float] = (0.4, 2.5)
    release: tuple[float, float] = (0.2, 0.8)
    expression_intensity: tuple[float, float] = (0.35, 1.0)
    muscle_jitter: tuple[float, float] = (0.8, 1.15)
    speech_length: tuple[float, float] = (1.5, 5.0)
    syllable_rate: tuple[float, float] = (3.0, 6.0)
    speech_fade: float = 0.15
    rest_length: tuple[float, float] = (0.5, 2.0)
    next_event_after: tuple[float, float] = (0.6, 1.1)  # fraction of the event's length; below 1 overlaps
    idle_level: float = 0.05
    idle_knot_spacing: float = 0.7


STYLE = PerformanceStyle()
_COLUMN = {name: index for index, name in enumerate(MUSCLE_NAMES)}
_SIDED = tuple(name for name in MUSCLE_NAMES if name.endswith(("_L", "_R")))


def make_activations(n_frames: int, frame_rate: float, rng: np.random.Generator) -> np.ndarray:
    """Muscle activation curves of a performance.

    Parameters
    ----------
    n_frames : int
        Number of frames, at least 1.
    frame_rate : float
        Frames per second, positive.
    rng : numpy.random.Generator
        The only source of randomness.

    Returns
    -------
    activations : ndarray of shape (n_frames, 18)
        Activation of each muscle of ``MUSCLE_NAMES`` in [0, 1]; all zero during the first second.
    """
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1:
        raise WorkbenchError(f"n_frames must be a positive integer, got {n_frames!r}")
    if not (isinstance(frame_rate, (int, float, np.number)) and np.isfinite(frame_rate) and frame_rate > 0):
        raise WorkbenchError(f"frame_rate must be a positive finite number, got {frame_rate!r}")
    if not isinstance(rng, np.random.Generator):
        raise WorkbenchError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    times = np.arange(int(n_frames)) / float(frame_rate)
    relaxed = np.ones((times.size, N_MUSCLES))  # running product of (1 - c_k)
    _combine(relaxed, slice(None), _idle(times, rng))
    for window, contribution in _events(times, float(frame_rate), rng):
        _combine(relaxed, window, contribution)
    return np.clip(1.0 - relaxed, 0.0, 1.0)


def _combine(relaxed: np.ndarray, window: slice, contribution: np.ndarray) -> None:
    relaxed[window] *= 1.0 - np.clip(contribution, 0.0, 1.0)


def _envelope(local_time: np.ndarray, attack: float, hold: float, release: float) -> np.ndarray:
    """Raised-cosine attack, flat hold, raised-cosine release; local_time starts at 0."""
    rise = 0.5 - 0.5 * np.cos(np.pi * np.clip(local_time / attack, 0.0, 1.0))
    fall = 0.5 + 0.5 * np.cos(np.pi * np.clip((local_time - attack - hold) / release, 0.0, 1.0))
    return rise * fall


def _events(times: np.ndarray, frame_rate: float, rng: np.random.Generator):
    """Yield ``(window, contribution)`` with contribution of shape (window length, 18)."""
    duration = times[-1] + 1.0 / frame_rate
    start = STYLE.lead_rest
    kinds = ("expression", "speech", "single", "rest")
    while start < duration:
        kind = kinds[rng.choice(len(kinds), p=np.array(STYLE.event_weights) / sum(STYLE.event_weights))]
        if kind == "rest":
            start += rng.uniform(*STYLE.rest_length)
            continue
        if kind == "speech":
            length = rng.uniform(*STYLE.speech_length)
        else:
            attack, hold, release = (rng.uniform(*STYLE.attack), rng.uniform(*STYLE.hold), rng.uniform(*STYLE.release))
            length = attack + hold + release
        first, stop = int(np.ceil(start * frame_rate)), int(np.ceil((start + length) * frame_rate))
        window = slice(first, min(stop, times.size))
        local_time = times[window] - start
        if local_time.size:
            if kind == "speech":
                contribution = _speech(local_time, length, rng)
            else:
                levels = _expression_levels(rng) if kind == "expression" else _single_muscle_levels(rng)
                contribution = _envelope(local_time, attack, hold, release)[:, None] * levels
            yield window, contribution
        start += length * rng.uniform(*STYLE.next_event_after)


def _expression_levels(rng: np.random.Generator) -> np.ndarray:
    expression = EXPRESSIONS[rng.integers(len(EXPRESSIONS))]
    intensity = rng.uniform(*STYLE.expression_intensity)
    levels = np.zeros(N_MUSCLES)
    for muscle, level in expression.levels:
        levels[_COLUMN[muscle]] = level * intensity * rng.uniform(*STYLE.muscle_jitter)
    return np.clip(levels, 0.0, 1.0)


def _single_muscle_levels(rng: np.random.Generator) -> np.ndarray:
    levels = np.zeros(N_MUSCLES)
    levels[_COLUMN[_SIDED[rng.integers(len(_SIDED))]]] = rng.uniform(0.3, 1.0)
    return levels


def _speech(local_time: np.ndarray, length: float, rng: np.random.Generator) -> np.ndarray:
    """Jaw and lip muscles oscillating at a drifting syllable rate with per-syllable amplitudes."""
    rate = rng.uniform(*STYLE.syllable_rate)
    drift = 1.0 + 0.15 * np.sin(2.0 * np.pi * rng.uniform(0.2, 0.5) * local_time + rng.uniform(0, 2 * np.pi))
    phase = 2.0 * np.pi * rate * np.concatenate([[0.0], np.cumsum(drift[:-1] * np.diff(local_time))])
    syllable = phase / (2.0 * np.pi)
    loudness = np.interp(syllable, np.arange(int(syllable[-1]) + 3), rng.uniform(0.3, 1.0, int(syllable[-1]) + 3))
    fade = np.minimum(_envelope(local_time, STYLE.speech_fade, length - 2 * STYLE.speech_fade, STYLE.speech_fade), 1.0)
    open_close = 0.5 - 0.5 * np.cos(phase)
    curves = {
        "jaw_open": rng.uniform(0.25, 0.55) * loudness * open_close,
        "orbicularis_oris": rng.uniform(0.1, 0.5) * (0.5 - 0.5 * np.cos(0.5 * phase + rng.uniform(0, 2 * np.pi))) ** 2,
        "depressor_labii": rng.uniform(0.1, 0.4) * loudness * (0.5 - 0.5 * np.cos(phase + 0.4)),
        "mentalis": rng.uniform(0.0, 0.3) * (0.5 + 0.5 * np.cos(phase)) ** 3,
    }
    spread = rng.uniform(0.0, 0.3) * (0.5 + 0.5 * np.cos(0.7 * phase + rng.uniform(0, 2 * np.pi)))
    lift = rng.uniform(0.0, 0.25) * (0.5 + 0.5 * np.cos(0.45 * phase + rng.uniform(0, 2 * np.pi)))
    for side, balance in (("_L", rng.uniform(0.85, 1.0)), ("_R", rng.uniform(0.85, 1.0))):
        curves["risorius" + side] = balance * spread
        curves["levator_labii" + side] = balance * lift
        curves["zygomatic_major" + side] = 0.3 * balance * spread
    contribution = np.zeros((local_time.size, N_MUSCLES))
    for muscle, curve in curves.items():
        contribution[:, _COLUMN[muscle]] = fade * curve
    return contribution


def _idle(times: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Low, slowly wandering muscle tone after the leading rest: (n_frames, 18)."""
    n_knots = int(times[-1] / STYLE.idle_knot_spacing) + 2
    knot_values = rng.uniform(0.0, STYLE.idle_level, (n_knots, N_MUSCLES))
    position = times / STYLE.idle_knot_spacing
    index = np.minimum(position.astype(int), n_knots - 2)
    blend = 0.5 - 0.5 * np.cos(np.pi * (position - index))  # cosine interpolation: smooth at the knots
    tone = knot_values[index] * (1.0 - blend[:, None]) + knot_values[index + 1] * blend[:, None]
    start_up = 0.5 - 0.5 * np.cos(np.pi * np.clip((times - STYLE.lead_rest) / 1.0, 0.0, 1.0))
    return tone * start_up[:, None]
