"""espeak-ng writes real speech; the voice driver speaks safety cues first.

In CI (CI=true) espeak-ng must be installed (``make system-deps``) and these tests never skip.
"""

from __future__ import annotations

import asyncio
import os
import time
import wave
from pathlib import Path

import pytest

from drivers.voice.driver import CueQueue, VoiceDriver
from drivers.voice.espeak import (
    INSTALL_HINT,
    EspeakSpeaker,
    SpeechCancelled,
    espeak_binary,
    wav_seconds,
)
from protocol.messages import CuePriority, VoiceCue

needs_espeak = pytest.mark.skipif(
    espeak_binary() is None and os.environ.get("CI") != "true", reason=INSTALL_HINT
)


def cue(text: str, safety: bool = False, stamp: float | None = None, lang: str = "en") -> VoiceCue:
    return VoiceCue(
        text=text,
        lang=lang,
        priority=CuePriority.SAFETY if safety else CuePriority.ROUTINE,
        kind="stop" if safety else "direction",
        stamp=time.time() if stamp is None else stamp,
    )


@needs_espeak
@pytest.mark.timeout(30)
@pytest.mark.parametrize(
    ("lang", "text"),
    [("en", "turn to 2 o'clock, then 3 metres"), ("es", "gira a las 2, luego 3 metros")],
)
def test_espeak_writes_a_wav_of_plausible_length(tmp_path: Path, lang: str, text: str) -> None:
    speaker = EspeakSpeaker(wav_dir=tmp_path)
    wav = asyncio.run(speaker.speak(text, lang))
    assert wav is not None and wav.exists() and wav.stat().st_size > 1000
    with wave.open(str(wav), "rb") as w:
        assert w.getnframes() > 0 and w.getnchannels() == 1
    # six or seven words at 165 words a minute: about two seconds
    assert 1.0 < wav_seconds(wav) < 5.0
    short = asyncio.run(speaker.speak("stop" if lang == "en" else "alto", lang))
    assert short is not None and 0.2 < wav_seconds(short) < wav_seconds(wav)
    assert speaker.spoken == 2


@needs_espeak
@pytest.mark.timeout(30)
def test_text_that_looks_like_an_option_is_spoken(tmp_path: Path) -> None:
    speaker = EspeakSpeaker(wav_dir=tmp_path)
    wav = asyncio.run(speaker.speak("--help -w /etc/passwd", "en"))
    assert wav is not None and wav_seconds(wav) > 0.5
    assert sorted(p.name for p in tmp_path.iterdir()) == [wav.name]


@needs_espeak
@pytest.mark.timeout(30)
def test_cancel_cuts_a_cue_short(tmp_path: Path) -> None:
    speaker = EspeakSpeaker(wav_dir=tmp_path)

    async def main() -> None:
        task = asyncio.ensure_future(speaker.speak("the quick brown fox. " * 2000, "en"))
        # The child speaking (not a fixed wait: starting it may take longer on a loaded
        # machine; a cancel before it exists has a test of its own, below).
        deadline = time.monotonic() + 10.0
        while speaker._proc is None:
            assert time.monotonic() < deadline and not task.done(), "espeak-ng never started"
            await asyncio.sleep(0.01)
        assert speaker.cancel()
        with pytest.raises(SpeechCancelled):
            await task

    asyncio.run(main())
    assert speaker.cancelled == 1 and not list(tmp_path.iterdir())


@needs_espeak
@pytest.mark.timeout(30)
def test_a_cancel_while_the_child_is_still_starting_cuts_the_cue(tmp_path: Path) -> None:
    """A safety cue can come while espeak-ng is being started for a routine one (a fork and
    an exec: long on a loaded machine). cancel() then found no child and said nothing was
    being said, so the routine cue was said to its end before the safety cue."""
    speaker = EspeakSpeaker(wav_dir=tmp_path)
    assert not speaker.cancel()  # nothing being said

    async def main() -> None:
        task = asyncio.ensure_future(speaker.speak("the quick brown fox. " * 2000, "en"))
        await asyncio.sleep(0)  # speak() has begun starting its child, which is not there yet
        assert speaker._proc is None and not task.done()
        assert speaker.cancel()
        with pytest.raises(SpeechCancelled):
            await task
        assert not speaker.cancel()  # over: the next cue is not cut by this one's cancel
        short = await speaker.speak("stop", "en")
        assert short is not None and wav_seconds(short) > 0.2

    asyncio.run(main())
    assert speaker.cancelled == 1 and speaker.spoken == 1
    assert [p.name for p in tmp_path.iterdir()] == ["cue-00002-en.wav"]


def test_queue_orders_safety_first_and_keeps_the_newest_routine() -> None:
    q = CueQueue(stale_s=5.0)
    now = time.time()
    q.push(cue("turn to 2 o'clock", stamp=now))
    q.push(cue("stop", safety=True, stamp=now))
    q.push(cue("turn to 3 o'clock", stamp=now))
    q.push(cue("no path", safety=True, stamp=now))
    assert [q.pop(now).text for _ in range(3)] == ["stop", "no path", "turn to 3 o'clock"]
    assert q.pop(now) is None and q.dropped == 1
    q.push(cue("old direction", stamp=now - 10))
    assert q.pop(now) is None and q.dropped == 2


class SlowSpeaker(EspeakSpeaker):
    """espeak-ng writing WAVs, but every cue lasts at least ``hold_s``, like speech playing
    on a loudspeaker, so a test can send a safety cue while a routine one is being said."""

    def __init__(self, wav_dir: Path, hold_s: float) -> None:
        super().__init__(wav_dir=wav_dir)
        self.hold_s = hold_s
        self._sleeper: asyncio.Future | None = None
        self.started: list[str] = []

    async def speak(self, text: str, lang: str = "en"):
        self.started.append(text)
        wav = await super().speak(text, lang)
        self._sleeper = asyncio.ensure_future(asyncio.sleep(self.hold_s))
        try:
            await self._sleeper
        except asyncio.CancelledError:
            if self._cut:
                self.cancelled += 1
                raise SpeechCancelled(text) from None
            raise
        finally:
            self._sleeper = None
        return wav

    def cancel(self) -> bool:
        if self._sleeper is not None and not self._sleeper.done():
            self._cut = True
            self._sleeper.cancel()
            return True
        return super().cancel()


@needs_espeak
@pytest.mark.timeout(30)
def test_driver_over_zenoh_speaks_and_safety_preempts(tmp_path: Path) -> None:
    from daemon.service.embedded import free_port
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.session import loopback, open_session

    port = free_port()
    speaker = SlowSpeaker(tmp_path, hold_s=1.0)

    async def main() -> VoiceDriver:
        stop = asyncio.Event()
        with open_session(loopback(listen_port=port)) as s1, open_session(
            loopback(connect_port=port)
        ) as s2:
            driver = VoiceDriver(s1, speaker, user="ana")
            runner = asyncio.ensure_future(driver.run(stop))
            await asyncio.sleep(0.5)  # let the subscription reach the publisher's session
            pub = wire.declare_publisher(s2, T.VOICE, "ana")
            for _ in range(50):  # until the route is up: a put before it would be lost
                pub.put(codec.encode(cue("turn to 2 o'clock, then 3 metres")))
                await asyncio.sleep(0.1)
                if speaker.started:
                    break
            pub.put(b"{not json")
            pub.put(codec.encode(cue("stop", safety=True)))
            wire.put(s2, T.VOICE, "bob", codec.encode(cue("not for ana")))
            for _ in range(100):
                if driver.said:
                    break
                await asyncio.sleep(0.05)
            stop.set()
            await asyncio.wait_for(runner, 10)
            pub.undeclare()
        return driver

    driver = asyncio.run(main())
    assert driver.cut[0].text == "turn to 2 o'clock, then 3 metres"
    assert driver.said[0][0].text == "stop"  # cut in at once, ahead of any routine cue
    assert "not for ana" not in [c.text for c, _ in driver.said]
    assert driver.rejected == 1
    wav = driver.said[0][1]
    assert isinstance(wav, Path) and wav_seconds(wav) > 0.2
