"""How well the goal listener hears landmark names: espeak-ng speaks them, noise is added.

Each name is synthesised by espeak-ng (the en-us voice) at two speeds, then heard clean
(with a faint dither: digital silence is no microphone's) and with white noise at a given
SNR (relative to the active speech level, ``active_power``). Unlisted phrases are put
through the whole dialog with a "no" as the answer to the read-back, and must never become
a goal.
"""

from __future__ import annotations

import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drivers.voice.goal_listener import LEAD_S, RATE_HZ, GoalDialog, GoalRecogniser, read_wav

SPEEDS_WPM = (130, 175)
"""A slow, careful request and espeak-ng's default pace."""
DITHER = 8.0
"""Clean speech's noise floor (16-bit units): about −72 dBFS."""
UNLISTED = ("hello there", "what time is it", "open the window", "where am I",
            "good morning", "turn left")  # fmt: skip


def synthesise(text: str, wpm: int, voice: str = "en-us") -> np.ndarray:
    """espeak-ng's rendering of ``text`` at 16 kHz."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "say.wav"
        cmd = ["espeak-ng", "-v", voice, "-s", str(wpm), "-w", str(out), "--stdin"]
        subprocess.run(cmd, input=text.encode(), check=True, capture_output=True, timeout=30)
        speech = read_wav(out)
    # A recording holds the room before and after the words: noise is added over all of it.
    pad = np.zeros(int(LEAD_S * RATE_HZ))
    return np.concatenate([pad, speech, pad])


ACTIVE_FRAME = 160
"""10 ms frames for the active speech level."""
ACTIVE_WITHIN_DB = 30.0
"""A frame within this of the loudest one is speech (the word's quiet consonants included)."""


def active_power(x: np.ndarray) -> float:
    """Mean power over the frames that hold speech: the active speech level, in the manner
    of ITU-T P.56 (a simpler activity rule than its envelope detector).

    SNR is speech power over noise power while the speech is on. Averaged over the whole
    recording instead, the silence around the word would dilute it (by 6–8 dB here) and
    the SNR would depend on how much room the recording holds, not on how loud the word
    is against the noise. Per sample (|x| above 1 % of the peak, the first version) it
    dropped each waveform's zero crossings and overstated the level by 0.8–1.8 dB."""
    n = x.size // ACTIVE_FRAME * ACTIVE_FRAME
    energy = (np.asarray(x[:n], np.float64).reshape(-1, ACTIVE_FRAME) ** 2).mean(axis=1)
    return float(energy[energy >= energy.max() * 10 ** (-ACTIVE_WITHIN_DB / 10)].mean())


def with_noise(x: np.ndarray, snr_db: float | None, rng: np.random.Generator) -> np.ndarray:
    """White noise at ``snr_db`` below the active speech level (None: the dither only)."""
    if snr_db is None:
        return x + rng.normal(0.0, DITHER, x.size)
    power = active_power(x)
    return x + rng.normal(0.0, np.sqrt(power / 10 ** (snr_db / 10)), x.size)


@dataclass
class VoiceEval:
    heard: int = 0
    trials: int = 0
    misses: list[tuple[str, int, float | None, str | None]] = field(default_factory=list)
    unlisted_goals: int = 0
    unlisted_trials: int = 0
    unlisted_reached_readback: int = 0

    @property
    def rate(self) -> float:
        return self.heard / max(1, self.trials)


def evaluate(
    landmarks: list[str],
    *,
    snrs: tuple[float | None, ...] = (None, 10.0),
    noisy_trials: int = 3,
    unlisted: tuple[str, ...] = UNLISTED,
    seed: int = 0,
) -> VoiceEval:
    """Every name at both speeds, clean once and ``noisy_trials`` times per noisy SNR."""
    rec = GoalRecogniser(landmarks)
    rng = np.random.default_rng(seed)
    res = VoiceEval()
    for name in landmarks:
        for wpm in SPEEDS_WPM:
            speech = synthesise(name, wpm)
            for snr in snrs:
                for _ in range(1 if snr is None else noisy_trials):
                    got = rec.landmark(with_noise(speech, snr, rng))
                    res.trials += 1
                    res.heard += got == name
                    if got != name:
                        res.misses.append((name, wpm, snr, got))
    no = synthesise("no", SPEEDS_WPM[1])
    for phrase in unlisted:
        for wpm in SPEEDS_WPM:
            dialog = GoalDialog(rec)
            first = dialog.hear(with_noise(synthesise(phrase, wpm), None, rng))
            res.unlisted_trials += 1
            res.unlisted_reached_readback += dialog.pending is not None
            second = dialog.hear(with_noise(no, None, rng))
            res.unlisted_goals += (first.goal or second.goal) is not None
    return res
