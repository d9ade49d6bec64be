"""The voice driver: a zenoh node that speaks the VoiceCues published for a user.

Safety first:
- safety cues wait in a FIFO ahead of every routine cue, and one arriving while a routine cue
  is being spoken cuts that cue short;
- of routine cues only the newest is kept (a direction from two seconds ago is wrong now),
  and one older than ``stale_s`` when its turn comes is dropped.

Zenoh delivers samples on its own threads; the callback only decodes and hands the cue to the
asyncio loop (``call_soon_threadsafe``). Undecodable payloads are counted and dropped.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import logging
import time
from dataclasses import dataclass, field

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import CuePriority, VoiceCue

from .espeak import EspeakSpeaker, SpeechCancelled, SpeechError

log = logging.getLogger(__name__)


@dataclass
class CueQueue:
    """What to say next: safety FIFO first, then the single newest routine cue."""

    stale_s: float = 5.0
    max_safety: int = 16
    safety: collections.deque[VoiceCue] = field(default_factory=collections.deque)
    routine: VoiceCue | None = None
    dropped: int = 0

    def push(self, cue: VoiceCue) -> None:
        if cue.priority is CuePriority.SAFETY:
            if len(self.safety) >= self.max_safety:
                self.safety.popleft()  # the oldest warning is the least true one
                self.dropped += 1
            self.safety.append(cue)
        else:
            if self.routine is not None:
                self.dropped += 1
            self.routine = cue

    def pop(self, now: float) -> VoiceCue | None:
        if self.safety:
            return self.safety.popleft()
        cue, self.routine = self.routine, None
        if cue is not None and now - cue.stamp > self.stale_s:
            self.dropped += 1
            return None
        return cue

    def __len__(self) -> int:
        return len(self.safety) + (self.routine is not None)


class VoiceDriver:
    """Subscribes to ``guidebelt/<user>/voice`` (every user when ``user`` is None) and speaks."""

    def __init__(
        self,
        session: zenoh.Session,
        speaker: EspeakSpeaker,
        user: str | None = None,
        stale_s: float = 5.0,
    ) -> None:
        self.session = session
        self.speaker = speaker
        self.user = user
        self.key = T.VOICE.selector(user)
        self.queue = CueQueue(stale_s=stale_s)
        self.rejected = 0
        self.said: list[tuple[VoiceCue, object]] = []
        """Every cue spoken to the end, with what the speaker returned (its WAV, if any)."""
        self.cut: list[VoiceCue] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: asyncio.Event | None = None
        self._speaking: VoiceCue | None = None
        self._sub = None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        """Zenoh's thread: decode, then hand over; never block here."""
        try:
            cue = codec.decode(VoiceCue, sample.payload.to_bytes())
        except ValueError as exc:
            self.rejected += 1
            log.warning("voice cue rejected: %s", exc)
            return
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed between check and call
                loop.call_soon_threadsafe(self._push, cue)

    def _push(self, cue: VoiceCue) -> None:
        self.queue.push(cue)
        speaking = self._speaking
        if (
            cue.priority is CuePriority.SAFETY
            and speaking is not None
            and speaking.priority is CuePriority.ROUTINE
        ):
            self.speaker.cancel()
        assert self._wake is not None
        self._wake.set()

    async def run(self, stop: asyncio.Event) -> None:
        """Speak cues until ``stop`` is set."""
        self._loop = asyncio.get_running_loop()
        self._wake = asyncio.Event()
        self._sub = wire.declare_subscriber(
            self.session, T.VOICE, Callback(self._on_sample, indirect=False), self.user
        )
        stopper = asyncio.ensure_future(stop.wait())
        try:
            while not stop.is_set():
                cue = self.queue.pop(time.time())
                if cue is None:
                    self._wake.clear()
                    if len(self.queue):
                        continue
                    waiter = asyncio.ensure_future(self._wake.wait())
                    await asyncio.wait({waiter, stopper}, return_when=asyncio.FIRST_COMPLETED)
                    waiter.cancel()
                    continue
                await self._say(cue)
        finally:
            stopper.cancel()
            self._sub.undeclare()
            self._sub = None
            self._loop = None

    async def _say(self, cue: VoiceCue) -> None:
        self._speaking = cue
        try:
            result = await self.speaker.speak(cue.text, cue.lang)
            self.said.append((cue, result))
        except SpeechCancelled:
            self.cut.append(cue)
        except SpeechError as exc:
            log.error("could not speak %r: %s", cue.text, exc)
        finally:
            self._speaking = None
