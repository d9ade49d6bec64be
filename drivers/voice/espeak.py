"""Speech with espeak-ng, the Debian package (``make system-deps`` installs it).

espeak-ng runs as a child process through asyncio, never through a shell: the text goes in on
stdin (``--stdin``), so nothing a cue says can be taken for an option. Either it plays on the
audio device, or, with ``wav_dir``, it writes one numbered WAV file per cue (``-w``) — what the
tests, CI and a headless demo use. A cue being spoken can be cut short (``cancel``) when a
safety cue arrives.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import shutil
import wave
from pathlib import Path

VOICES = {"en": "en", "es": "es"}
"""Our language codes → espeak-ng voice names."""

INSTALL_HINT = "espeak-ng is not installed: run `make system-deps` (apt-get install espeak-ng)"


class SpeechError(RuntimeError):
    """espeak-ng is missing or failed."""


class SpeechCancelled(Exception):
    """The cue was cut short by ``cancel`` (a safety cue pre-empted it)."""


def espeak_binary(name: str = "espeak-ng") -> str | None:
    return shutil.which(name)


def wav_seconds(path: Path) -> float:
    """Duration of a WAV file in seconds."""
    with wave.open(str(path), "rb") as w:
        return w.getnframes() / float(w.getframerate())


class EspeakSpeaker:
    """Speaks one text at a time; ``speak`` returns the WAV path when writing files."""

    def __init__(
        self,
        *,
        wav_dir: Path | None = None,
        words_per_minute: int = 165,
        binary: str = "espeak-ng",
        timeout_s: float = 20.0,
    ) -> None:
        path = espeak_binary(binary)
        if path is None:
            raise SpeechError(INSTALL_HINT)
        self.binary = path
        self.wav_dir = Path(wav_dir) if wav_dir is not None else None
        if self.wav_dir is not None:
            self.wav_dir.mkdir(parents=True, exist_ok=True)
        self.wpm = int(words_per_minute)
        self.timeout_s = timeout_s
        self._count = itertools.count(1)
        self._proc: asyncio.subprocess.Process | None = None
        self._speaking = False
        """From ``speak``'s call to its return: a cue is being said, its child started or not."""
        self._cut = False
        self.spoken = 0
        self.cancelled = 0

    def _argv(self, lang: str, wav: Path | None) -> list[str]:
        if lang not in VOICES:
            raise SpeechError(f"no espeak-ng voice for language {lang!r}")
        argv = [self.binary, "--stdin", "-b", "1", "-v", VOICES[lang], "-s", str(self.wpm)]
        if wav is not None:
            argv += ["-w", str(wav)]
        return argv

    async def speak(self, text: str, lang: str = "en") -> Path | None:
        """Say ``text``; returns the WAV written (``wav_dir`` mode) or None (audio device).

        Raises ``SpeechCancelled`` if cut short by ``cancel``; on task cancellation the child
        is killed and reaped before ``CancelledError`` goes on.
        """
        wav = None
        if self.wav_dir is not None:
            wav = self.wav_dir / f"cue-{next(self._count):05d}-{lang}.wav"
        argv = self._argv(lang, wav)
        # Speaking from here, before the child exists: starting it takes a while (a fork and
        # an exec; much longer on a loaded machine), and a safety cue that comes meanwhile
        # must still cut this one short, not wait for all of it to be said.
        self._speaking, self._cut = True, False
        try:
            proc = await asyncio.create_subprocess_exec(
                *argv,
                stdin=asyncio.subprocess.PIPE,
                stdout=asyncio.subprocess.DEVNULL,
                stderr=asyncio.subprocess.PIPE,
            )
            self._proc = proc
            try:
                if self._cut:  # cancelled while the child started: it says nothing
                    await self._kill(proc)
                    err = b""
                else:
                    _, err = await asyncio.wait_for(
                        proc.communicate(text.encode("utf-8")), timeout=self.timeout_s
                    )
            except TimeoutError:
                await self._kill(proc)
                raise SpeechError(f"espeak-ng took longer than {self.timeout_s} s") from None
            except asyncio.CancelledError:
                await self._kill(proc)
                raise
        finally:
            self._proc, self._speaking = None, False
        if self._cut:
            self.cancelled += 1
            if wav is not None:
                wav.unlink(missing_ok=True)  # a cut-off cue is not a cue that was said
            raise SpeechCancelled(text)
        if proc.returncode != 0:
            raise SpeechError(f"espeak-ng exited {proc.returncode}: {err.decode(errors='replace')}")
        self.spoken += 1
        return wav

    def cancel(self) -> bool:
        """Stop what is being said now (a safety cue pre-empts it); True if something was."""
        proc = self._proc
        if not self._speaking or (proc is not None and proc.returncode is not None):
            return False
        self._cut = True  # a child still starting is killed as soon as it exists
        if proc is not None:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
        return True

    @staticmethod
    async def _kill(proc: asyncio.subprocess.Process) -> None:
        if proc.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
        await proc.wait()
