"""The goal by voice, end to end: espeak-ng speaks, PocketSphinx hears, the dialog confirms."""

from __future__ import annotations

import shutil
import wave

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

pytest.importorskip("pocketsphinx")
if shutil.which("espeak-ng") is None:
    pytest.skip("espeak-ng is not installed (make system-deps)", allow_module_level=True)

from cli import voice_goal as voice_goal_cli
from drivers.voice.goal_listener import (
    RATE_HZ,
    GoalDialog,
    GoalRecogniser,
    VoiceGoalError,
    filtered_variants,
    grammar,
    normalise,
    read_wav,
    resample,
)
from sim.voice_goal_eval import synthesise, with_noise

LANDMARKS = ["entrance", "fountain", "the door", "toilet"]


@pytest.fixture(scope="module")
def recogniser() -> GoalRecogniser:
    return GoalRecogniser(LANDMARKS)


def test_names_become_a_grammar_of_those_names_only() -> None:
    assert normalise("The_Door") == "door" and normalise("Main-Exit") == "main exit"
    g = grammar(["door", "fountain"])
    assert "public <goal> = ( door ) | ( fountain );" in g
    with pytest.raises(VoiceGoalError, match="qzxv"):
        GoalRecogniser(["qzxv"])
    with pytest.raises(VoiceGoalError):
        GoalRecogniser([])


def test_resampling_keeps_a_tone_and_its_length() -> None:
    t = np.arange(22050) / 22050
    tone = 1000 * np.sin(2 * np.pi * 440 * t)
    out = resample(tone, 22050)
    assert out.size == RATE_HZ
    spectrum = np.abs(np.fft.rfft(out))
    assert abs(int(np.argmax(spectrum)) - 440) <= 1  # 1 s at 16 kHz: 1 Hz per bin


@pytest.mark.timeout(60)
def test_the_names_are_heard_clean_at_two_speeds(recogniser) -> None:
    """Measured 22 of 24 (fountain at 130 wpm is the weak one); a miss is either no name
    ("say again") or a wrong one, which the read-back is there to catch."""
    heard = 0
    for name in LANDMARKS:
        for wpm in (130, 175):
            speech = synthesise(name, wpm)
            for seed in range(3):
                got = recogniser.landmark(with_noise(speech, None, np.random.default_rng(seed)))
                heard += got == name
    assert heard >= 21


@pytest.mark.timeout(60)
def test_the_names_are_heard_in_noise_at_10_db(recogniser) -> None:
    """White noise 10 dB below the active speech level; the Wiener front end is what hears
    them (without it 69 % of the eight-name set). Measured here: 16 of 16."""
    heard = 0
    for name in LANDMARKS:
        for wpm in (130, 175):
            speech = synthesise(name, wpm)
            for seed in range(2):
                noisy = with_noise(speech, 10.0, np.random.default_rng(100 + seed))
                heard += recogniser.landmark(noisy) == name
    assert heard >= 15


def test_the_noisy_search_also_hears_a_name_without_the_fricative_the_filter_takes() -> None:
    assert filtered_variants("EH G Z IH T") == ["EH G IH T"]  # exit
    assert filtered_variants("T AE K S IY K S") == ["T AE K IY K S", "T AE K S IY K",
                                                    "T AE K IY K"]  # fmt: skip
    assert filtered_variants("F AW N T AH N") == []  # fountain: nothing to drop
    rec = GoalRecogniser(["exit", "fountain"])
    assert rec._filtered_phrases() == ["( exit | exit_wf )", "fountain"]  # twice: no error
    assert rec.decoder.lookup_word("exit_wf") is not None


@pytest.mark.timeout(90)
def test_exit_is_heard_at_10_db() -> None:
    """Round 2's misses at 10 dB were "exit" (heard as entrance, fountain or lift). Among the
    eight names, these 20 noisy draws: 17 heard with the filtered variant, 14 without."""
    rec = GoalRecogniser(["the door", "exit", "toilet", "entrance", "fountain", "kitchen",
                          "stairs", "lift"])  # fmt: skip
    heard = 0
    for wpm in (130, 175):
        speech = synthesise("exit", wpm)
        for seed in range(10):
            noisy = with_noise(speech, 10.0, np.random.default_rng(200 + seed))
            heard += rec.landmark(noisy) == "exit"
    assert heard >= 16


@pytest.mark.timeout(60)
def test_read_back_then_only_yes_sends_the_goal(recogniser) -> None:
    rng = np.random.default_rng(1)
    dialog = GoalDialog(recogniser)
    first = dialog.hear(with_noise(synthesise("fountain", 150), None, rng))
    assert first.goal is None and first.say == "Fountain? Say yes or no."
    second = dialog.hear(with_noise(synthesise("yes", 150), None, rng))
    assert second.goal == "fountain" and "fountain" in second.say
    # "No" drops it; silence is never a goal.
    dialog.hear(with_noise(synthesise("entrance", 150), None, rng))
    assert dialog.hear(with_noise(synthesise("no", 150), None, rng)).goal is None
    quiet = dialog.hear(rng.normal(0, 8, RATE_HZ))
    assert quiet.goal is None and quiet.say == "Say again."


@pytest.mark.timeout(60)
def test_an_unlisted_phrase_never_becomes_a_goal(recogniser) -> None:
    rng = np.random.default_rng(2)
    no = with_noise(synthesise("no", 175), None, rng)
    for phrase in ("what time is it", "hello there"):
        dialog = GoalDialog(recogniser)
        replies = [dialog.hear(with_noise(synthesise(phrase, 150), None, rng)), dialog.hear(no)]
        assert all(r.goal is None for r in replies)
    # In noise too, and when the answer to the read-back is noise, another name or a word
    # that is neither yes nor no (none of these is in NOT_AN_ANSWER): with yes and no
    # alone the search heard "fountain" as "yes" and sent it.
    room = rng.normal(0, 300, RATE_HZ)
    answers = [no, room] + [synthesise(w, 150) for w in ("fountain", "yellow", "thank you")]
    for phrase in ("open the window", "good morning"):
        for answer in answers:
            dialog = GoalDialog(recogniser)
            heard = dialog.hear(with_noise(synthesise(phrase, 130), 10.0, rng))
            assert heard.goal is None
            assert dialog.hear(with_noise(answer, 10.0, rng)).goal is None


@pytest.mark.timeout(60)
def test_voice_goal_command_over_wav_files(tmp_path) -> None:
    paths = []
    for k, text in enumerate(("toilet", "yes")):
        x = np.clip(
            with_noise(synthesise(text, 150), None, np.random.default_rng(k)), -32768, 32767
        )
        path = tmp_path / f"{k}.wav"
        with wave.open(str(path), "wb") as w:
            w.setnchannels(1)
            w.setsampwidth(2)
            w.setframerate(RATE_HZ)
            w.writeframes(x.astype("<i2").tobytes())
        paths.append(path)
    assert read_wav(paths[0]).size > RATE_HZ // 2
    app = typer.Typer()
    voice_goal_cli.register(app)
    args = ["bob", "--no-send", *[a for p in paths for a in ("--wav", str(p))]]
    args += [a for name in LANDMARKS for a in ("--landmark", name)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "Toilet? Say yes or no." in result.output and "goal: toilet" in result.output
