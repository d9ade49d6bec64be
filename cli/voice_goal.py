"""``guidebelt voice-goal``: hear a landmark name, say it back, send the Goal on "yes"."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path
from typing import Annotated

import typer

from .peer import Connect, Scout, open_peer


def voice_goal(
    user: Annotated[str, typer.Argument(help="user name, [a-z0-9_-]")],
    wav: Annotated[
        list[Path], typer.Option(help="Utterances in order (the name, then yes/no); repeatable.")
    ],
    config: Annotated[
        Path | None, typer.Option(help="Daemon config whose [landmarks] are listened for.")
    ] = None,
    landmark: Annotated[
        list[str] | None, typer.Option(help="Listen for these names instead of the config's.")
    ] = None,
    speak: Annotated[bool, typer.Option(help="Say the replies aloud with espeak-ng.")] = False,
    send: Annotated[bool, typer.Option(help="Publish the confirmed Goal on zenoh.")] = True,
    connect: Connect = None,
    scout: Scout = False,
) -> None:
    """Run the goal dialog over WAV files (a microphone later) and send the confirmed goal."""
    from drivers.voice.goal_listener import GoalDialog, GoalRecogniser, VoiceGoalError, read_wav

    names = list(landmark or [])
    if not names:
        from daemon.service.config import load_config

        names = list(load_config(config).landmarks)
    try:
        dialog = GoalDialog(GoalRecogniser(names))
    except VoiceGoalError as exc:
        raise typer.BadParameter(str(exc)) from exc
    goal_name = None
    for path in wav:
        reply = dialog.hear(read_wav(path))
        typer.echo(f"{path.name}: {reply.say}")
        if speak:
            subprocess.run(["espeak-ng", "--stdin"], input=reply.say.encode(), check=False)
        if reply.goal is not None:
            goal_name = reply.goal
            break
    if goal_name is None:
        typer.echo("no goal")
        raise typer.Exit(1)
    if send:
        from protocol import codec
        from protocol import session as wire
        from protocol import topics as T
        from protocol.messages import Goal, GoalLandmark

        T.check_user(user)
        session = open_peer(connect, scout)
        try:
            time.sleep(0.1)  # let the peer link come up before the one put
            msg = Goal(target=GoalLandmark(name=goal_name), stamp=time.time())
            wire.put(session, T.GOAL, user, codec.encode(msg))
        finally:
            session.close()
    typer.echo(f"goal: {goal_name}")


def register(app: typer.Typer) -> None:
    app.command("voice-goal")(voice_goal)
