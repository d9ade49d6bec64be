"""The goal by voice: a landmark name heard offline, confirmed back, then sent as a Goal.

Chen et al.'s robot "obtain[s] the information of the target point G by voice input
functionality of voice module". Here PocketSphinx (its 5.x wheel ships the en-us acoustic
model and dictionary, so nothing is downloaded at run time) listens with a JSGF grammar
made of the config's landmark names only: whatever is said, the search can only end on one
of them (a leading "the" of a name is dropped: "the door" is heard as "door"; carrier words
such as "take me to" and an optional "the" were tried and cost names in noise, so the
grammar is the bare names). A closed grammar always finds
its best name, even for words that are no landmark at all, so a name is never sent on one
hearing: the listener says it back ("Fountain? Say yes or no.") and listens again with a
yes/no grammar; only "yes" sends the goal. Silence, a partial match or "no" gets "Say
again." and no goal.

Audio comes as 16-bit mono WAV at any rate (``read_wav``: the standard ``wave`` module and
a numpy windowed-sinc resampler to the model's 16 kHz) — from a file now, a microphone
later (``GoalDialog.hear`` takes the samples either way). Noisy input goes through a Wiener
filter first (``denoise.front_end``): at 10 dB SNR (white noise) it took the eight test
names heard right from 69 % to 94 %, and the names' filtered pronunciations in the noisy
search (``filtered_variants``: "exit" without the fricative the filter takes) to 96 %.
"""

from __future__ import annotations

import re
import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .denoise import front_end

RATE_HZ = 16_000
"""The en-us acoustic model's sample rate."""
LEAD_S = 0.5
"""Silence put around an utterance: the decoder's noise and cepstral-mean estimates need it."""
YES, NO = "yes", "no"
NOT_AN_ANSWER = ("maybe", "yesterday", "yet", "guess", "less", "says", "yell", "chess",
                 "what", "wait", "hello", "okay", "know", "now", "go", "nor", "note",
                 "stop", "again", "sorry")  # fmt: skip
"""Words the read-back's answer may be, or sound like, that are not "yes" or "no": each
is a place for the yes/no search to land other than "yes" (a miss there only asks again)."""


FILTERED_SUFFIX = "_wf"
"""The dictionary twin of a name's word that carries its Wiener-filtered variants."""
MASKED_FRICATIVES = (("G", "Z"), ("K", "S"))
"""A stop's voiced or voiceless fricative release ("exit": EH G Z IH T, EH K S AH T)."""


def filtered_variants(phones: str) -> list[str]:
    """A pronunciation as the decoder hears it after the Wiener filter in broadband noise:
    a fricative after a stop is noise-like, so the filter's gain takes it with the noise
    and the stop is left alone ("exit" at 10 dB SNR was heard as "entrance", "fountain"
    or "lift": 7 of the 9 names missed in 144). One variant per cluster dropped, and one
    with all of them dropped."""
    ph = phones.split()
    spots = [i for i in range(len(ph) - 1) if (ph[i], ph[i + 1]) in MASKED_FRICATIVES]
    out = []
    for drop in [[i] for i in spots] + ([spots] if len(spots) > 1 else []):
        out.append(" ".join(p for j, p in enumerate(ph) if j - 1 not in drop))
    return out


class VoiceGoalError(ValueError):
    """A landmark name the recogniser cannot listen for (a word not in its dictionary)."""


def resample(x: np.ndarray, rate_hz: int, to_hz: int = RATE_HZ) -> np.ndarray:
    """Windowed-sinc low-pass below the new Nyquist, then linear interpolation."""
    x = np.asarray(x, dtype=np.float64)
    if rate_hz == to_hz or x.size == 0:
        return x
    cut = 0.47 * min(rate_hz, to_hz) / rate_hz  # cycles per input sample
    k = np.arange(-32, 33)
    taps = 2 * cut * np.sinc(2 * cut * k) * np.hamming(k.size)
    smooth = np.convolve(x, taps / taps.sum(), mode="same")
    n = round(x.size * to_hz / rate_hz)
    return np.interp(np.arange(n) * rate_hz / to_hz, np.arange(x.size), smooth)


def read_wav(path: str | Path) -> np.ndarray:
    """A 16-bit WAV file as float samples at 16 kHz mono."""
    with wave.open(str(path), "rb") as w:
        if w.getsampwidth() != 2:
            raise ValueError(f"{path}: 16-bit samples expected, got {8 * w.getsampwidth()}-bit")
        raw = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(np.float64)
        channels, rate = w.getnchannels(), w.getframerate()
    mono = raw.reshape(-1, channels).mean(axis=1)
    return resample(mono, rate)


def pcm16(samples: np.ndarray) -> bytes:
    """Samples with ``LEAD_S`` of silence either side, as the decoder's 16-bit bytes."""
    pad = np.zeros(int(LEAD_S * RATE_HZ))
    x = np.concatenate([pad, np.asarray(samples, dtype=np.float64), pad])
    return np.clip(np.round(x), -32768, 32767).astype("<i2").tobytes()


def normalise(name: str) -> str:
    """A landmark name as the grammar spells it: lower case, words apart, no leading 'the'."""
    words = re.sub(r"[_-]+", " ", name.lower()).split()
    if len(words) > 1 and words[0] == "the":
        words = words[1:]
    return " ".join(words)


def grammar(phrases: list[str]) -> str:
    """JSGF: exactly one of ``phrases``."""
    names = " | ".join(f"( {p} )" for p in phrases)
    return f"#JSGF V1.0;\ngrammar goal;\npublic <goal> = {names};\n"


class GoalRecogniser:
    """Two PocketSphinx searches on one decoder: the landmark grammar and yes/no."""

    def __init__(self, landmarks: list[str]) -> None:
        from pocketsphinx import Decoder  # the model ships inside the wheel

        if not landmarks:
            raise VoiceGoalError("no landmarks to listen for")
        self.decoder = Decoder(loglevel="FATAL")
        self.by_phrase: dict[str, str] = {}
        for name in landmarks:
            phrase = normalise(name)
            missing = [w for w in phrase.split() if self.decoder.lookup_word(w) is None]
            if missing:
                raise VoiceGoalError(f"landmark {name!r}: {missing} not in the dictionary")
            self.by_phrase[phrase] = name
        self.decoder.add_jsgf_string("goal", grammar(sorted(self.by_phrase)))
        self.decoder.add_jsgf_string("goal_noisy", grammar(self._filtered_phrases()))
        # Not yes or no alone: a closed grammar always ends on one of its words, and with
        # two it heard "fountain", "maybe" and "yesterday" as "yes" — a wrong goal sent.
        # Anything else the user may say has a word to land on, and only "yes" sends.
        others = sorted(set(self.by_phrase) | set(NOT_AN_ANSWER))
        alternatives = " | ".join(f"( {p} )" for p in [YES, NO, *others])
        yes_no = f"#JSGF V1.0;\ngrammar yn;\npublic <yn> = {alternatives};\n"
        self.decoder.add_jsgf_string("yesno", yes_no)

    def _pronunciations(self, word: str) -> list[str]:
        """Every pronunciation the dictionary holds for ``word`` (``exit``, ``exit(2)``, …)."""
        out, i = [], 1
        while (phones := self.decoder.lookup_word(word if i == 1 else f"{word}({i})")) is not None:
            out.append(phones)
            i += 1
        return out

    def _filtered_phrases(self) -> list[str]:
        """The names as the noisy search hears them: each word, or its ``FILTERED_SUFFIX``
        twin where the Wiener filter's variants differ (``filtered_variants``)."""
        phrases = []
        for phrase in sorted(self.by_phrase):
            words = []
            for word in phrase.split():
                variants = {v for p in self._pronunciations(word) for v in filtered_variants(p)}
                variants -= set(self._pronunciations(word))
                if not variants:
                    words.append(word)
                    continue
                twin = word + FILTERED_SUFFIX
                for i, phones in enumerate(sorted(variants)):
                    entry = twin if i == 0 else f"{twin}({i + 1})"
                    if self.decoder.lookup_word(entry) is None:
                        self.decoder.add_word(entry, phones, True)
                words.append(f"( {word} | {twin} )")
            phrases.append(" ".join(words))
        return phrases

    def _decode(self, search: str, samples: np.ndarray) -> str:
        heard_as, filtered = front_end(samples)
        d = self.decoder
        d.activate_search(f"{search}_noisy" if filtered and search == "goal" else search)
        d.start_utt()
        d.process_raw(pcm16(heard_as), full_utt=True)
        d.end_utt()
        hyp = d.hyp()
        heard = hyp.hypstr.strip() if hyp is not None else ""
        return " ".join(w.removesuffix(FILTERED_SUFFIX) for w in heard.split())

    def landmark(self, samples: np.ndarray) -> str | None:
        """The config's name of the landmark heard, or None (nothing, or only part of one)."""
        return self.by_phrase.get(normalise(self._decode("goal", samples)))

    def yes_no(self, samples: np.ndarray) -> bool | None:
        heard = self._decode("yesno", samples)
        return True if heard == YES else False if heard == NO else None


@dataclass(frozen=True)
class Reply:
    say: str
    """What the belt's voice says back."""
    goal: str | None = None
    """The landmark to send as the Goal, once confirmed."""


class GoalDialog:
    """Hear a name, say it back, send it only on "yes"; anything unclear: "Say again."."""

    def __init__(self, recogniser: GoalRecogniser) -> None:
        self.recogniser = recogniser
        self.pending: str | None = None

    @staticmethod
    def spoken(name: str) -> str:
        return normalise(name)

    def hear(self, samples: np.ndarray) -> Reply:
        if self.pending is None:
            name = self.recogniser.landmark(samples)
            if name is None:
                return Reply("Say again.")
            self.pending = name
            return Reply(f"{self.spoken(name).capitalize()}? Say yes or no.")
        answer = self.recogniser.yes_no(samples)
        name = self.pending
        if answer is None:
            return Reply("Yes or no?")
        self.pending = None
        if not answer:
            return Reply("Say again.")
        return Reply(f"Going to the {self.spoken(name)}.", goal=name)
