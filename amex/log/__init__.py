"""Episode logs: MCAP files for Foxglove (writer), a tolerant reader, and ``amex-log``.

:class:`EpisodeLogger` records one episode (see :mod:`amex.log.writer` for the channels; the arm's
transforms are built in :mod:`amex.log.frames`, the other messages in :mod:`amex.log.messages`);
:func:`read_log` reads a log back, recovering the completed chunks of a file cut by SIGKILL, and
decodes its protobuf channels without the protobuf package (:mod:`amex.log.protobuf`);
:func:`recover` rewrites the readable part as a valid indexed MCAP file. ``amex-log``
(:mod:`amex.app.log_cli`) shows, plots, exports and recovers logs, serves them to Foxglove in a
browser
(:mod:`amex.log.serve`, with the robot from :mod:`amex.log.urdf` and a layout from
:mod:`amex.log.layout`) and films them (:mod:`amex.log.video`, :mod:`amex.log.render`).
"""

from amex.core.errors import (
    EmptyLogError,
    LogError,
    LogExistsError,
    LogNotFoundError,
    NotMcapError,
    TruncatedLogError,
)
from amex.log.reader import ChannelInfo, LogData, LogMessage, read_log
from amex.log.recover import recover
from amex.log.writer import EpisodeLogger

__all__ = [
    "ChannelInfo",
    "EmptyLogError",
    "EpisodeLogger",
    "LogData",
    "LogError",
    "LogExistsError",
    "LogMessage",
    "LogNotFoundError",
    "NotMcapError",
    "TruncatedLogError",
    "read_log",
    "recover",
]
