"""A mock voice driver: a zenoh node that records every cue instead of speaking it."""

from __future__ import annotations

from pathlib import Path

import zenoh

from drivers.belt.recorder import Recorder
from protocol import topics as T
from protocol.messages import VoiceCue


class VoiceRecorder(Recorder[VoiceCue]):
    def __init__(
        self, session: zenoh.Session, user: str | None = None, out: Path | None = None
    ) -> None:
        super().__init__(session, T.VOICE, user, out)

    def texts(self, user: str | None = None) -> list[str]:
        with self._cond:
            return [r.msg.text for r in self.received if user in (None, r.user)]


if __name__ == "__main__":
    from drivers.belt.recorder import main

    main(VoiceRecorder, "voice cues")
