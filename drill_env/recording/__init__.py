"""Episodes in rerun: record them (``.rrd``, one file per episode) and replay them.

=====================  ====================================================================
module                 what it does
=====================  ====================================================================
``recorder``           :class:`EpisodeRecorder`: collects steps, streams them in chunks
``writer``             the rerun entities of a recording, and the viewer's blueprint
``wrapper``            :class:`RecordEpisode`: the Gymnasium wrapper that feeds a recorder
``replay``             :func:`replay` in the viewer (:func:`check_recording` first),
                       :func:`read_recording` back into arrays
=====================  ====================================================================

The event rules (stick-slip, whirl, layer change) are in :mod:`drill_env.events`, next
to the metrics they share. What a recording holds: ``docs/recording.md``.
"""

from drill_env.events import layer_events, stick_slip_events, whirl_events
from drill_env.recording.recorder import (
    DEFAULT_DIRECTORY,
    EpisodeRecorder,
    check_directory,
    stem_file_name,
)
from drill_env.recording.replay import (
    RecordingContents,
    check_recording,
    read_recording,
    replay,
    replay_command,
    stop_viewer,
)
from drill_env.recording.wrapper import RecordEpisode
from drill_env.recording.writer import APPLICATION_ID, SERIES, TIMELINE, Series

__all__ = [
    "APPLICATION_ID", "DEFAULT_DIRECTORY", "SERIES", "TIMELINE", "EpisodeRecorder",
    "RecordEpisode", "RecordingContents", "Series", "check_directory", "check_recording",
    "layer_events",
    "read_recording", "replay", "replay_command", "stem_file_name", "stick_slip_events",
    "stop_viewer", "whirl_events",
]
