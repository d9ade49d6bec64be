"""The goal listener's noisy-input front end, and the SNR the voice evaluation adds noise at."""

from __future__ import annotations

import numpy as np

from drivers.voice.denoise import DENOISE_BELOW_DB, estimate_snr_db, front_end, wiener
from drivers.voice.goal_listener import RATE_HZ
from sim.voice_goal_eval import active_power, with_noise


def _word(rng: np.random.Generator) -> np.ndarray:
    """0.5 s of room, a 0.4 s voiced burst (three harmonics of 150 Hz), 0.5 s of room."""
    t = np.arange(int(0.4 * RATE_HZ)) / RATE_HZ
    burst = sum(3000 / k * np.sin(2 * np.pi * 150 * k * t + rng.uniform(0, 6)) for k in (1, 2, 3))
    pad = np.zeros(RATE_HZ // 2)
    return np.concatenate([pad, burst * np.hanning(t.size), pad])


def test_snr_is_over_the_active_speech_not_the_silence_around_it() -> None:
    clean = _word(np.random.default_rng(0))
    voiced = clean[RATE_HZ // 2 : RATE_HZ // 2 + int(0.4 * RATE_HZ)]
    # Within 1.5 dB of the burst's own power (its faded ends are still speech), and far
    # above the whole recording's mean, which the room around the word dilutes.
    ratio = 10 * np.log10(active_power(clean) / np.mean(voiced**2))
    assert 0.0 <= ratio <= 1.5
    assert active_power(clean) > 2.5 * np.mean(clean**2)
    noisy = with_noise(clean, 10.0, np.random.default_rng(1))
    noise = noisy - clean
    assert abs(10 * np.log10(active_power(clean) / np.mean(noise**2)) - 10.0) < 0.2


def test_wiener_filter_takes_out_most_of_the_noise_and_keeps_the_word() -> None:
    rng = np.random.default_rng(2)
    clean = _word(rng)
    noisy = with_noise(clean, 10.0, rng)
    out = wiener(noisy)
    assert out.shape == noisy.shape
    before = np.mean((noisy - clean) ** 2)
    after = np.mean((out - clean) ** 2)
    assert after < before / 4  # more than 6 dB less error
    word = slice(RATE_HZ // 2, RATE_HZ // 2 + int(0.4 * RATE_HZ))
    kept = np.dot(out[word], clean[word]) / np.dot(clean[word], clean[word])
    assert 0.7 < kept <= 1.05


def test_clean_input_is_heard_raw_and_noisy_input_filtered() -> None:
    rng = np.random.default_rng(3)
    clean = _word(rng) + rng.normal(0, 8.0, _word(rng).size)
    assert estimate_snr_db(clean) > 40
    heard, filtered = front_end(clean)
    assert np.array_equal(heard, clean) and not filtered
    noisy = with_noise(_word(rng), 10.0, rng)
    assert estimate_snr_db(noisy) < DENOISE_BELOW_DB
    heard, filtered = front_end(noisy)
    assert not np.array_equal(heard, noisy) and filtered
    short = rng.normal(0, 100, 800)  # too short for a lead and a word: untouched
    heard, filtered = front_end(short)
    assert np.array_equal(heard, short) and not filtered
