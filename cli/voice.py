"""``guidebelt voice``: the voice driver — speaks a user's cues with espeak-ng.

Only typer and the standard library at the top; zenoh and the driver inside the command.
"""

from __future__ import annotations

import asyncio
import signal
from pathlib import Path
from typing import Annotated

import typer

from .peer import ZenohConfig, node_settings


def voice(
    user: Annotated[str | None, typer.Argument(help="User to speak for (default: every user).")] = (
        None
    ),
    connect: Annotated[
        list[str] | None, typer.Option(help="Zenoh endpoint to join, e.g. tcp/127.0.0.1:7447.")
    ] = None,
    listen: Annotated[list[str] | None, typer.Option(help="Zenoh endpoint to listen on.")] = None,
    scouting: Annotated[bool, typer.Option(help="Zenoh multicast scouting.")] = False,
    wav_dir: Annotated[
        Path | None, typer.Option(help="Write one WAV per cue here instead of playing it.")
    ] = None,
    wpm: Annotated[int, typer.Option(min=80, max=450, help="Speaking rate, words a minute.")] = (
        165
    ),
    stale_s: Annotated[float, typer.Option(help="Drop routine cues older than this.")] = 5.0,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Subscribe to the user's voice cues and speak them, safety cues first."""
    from drivers.voice.driver import VoiceDriver
    from drivers.voice.espeak import EspeakSpeaker, SpeechError
    from protocol.session import open_session

    try:
        speaker = EspeakSpeaker(wav_dir=wav_dir, words_per_minute=wpm)
    except SpeechError as exc:
        typer.echo(str(exc), err=True)
        raise typer.Exit(2) from None
    settings = node_settings(zenoh_config, connect, listen, scouting)

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        with open_session(settings) as session:
            driver = VoiceDriver(session, speaker, user=user, stale_s=stale_s)
            typer.echo(f"speaking cues from {driver.key}")
            await driver.run(stop)
            typer.echo(f"spoke {len(driver.said)} cues, cut {len(driver.cut)}, "
                       f"rejected {driver.rejected}")

    asyncio.run(main())


def register(app: typer.Typer) -> None:
    app.command("voice")(voice)
