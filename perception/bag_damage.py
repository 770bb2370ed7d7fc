"""What a damaged ROS1 bag lost while it was read: the account behind the reader's warning.

Filled by ``perception.rosbag1_reader.RecoveringReader`` (byte offsets are positions in the
bag file). ``read_bag`` logs ``summary()`` as a warning when the intact part was enough, and
appends it to its ``BagError`` when it was not.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

MAX_LISTED = 3  # corrupt chunks named one by one in the summary


@dataclass
class BagDamage:
    """Corrupt chunks, lost messages, and a rebuilt index of one ROS1 bag."""

    file_bytes: int  # size of the bag file (B)
    chunks: int = 0  # chunks the (own or rebuilt) index knows, corrupt ones included
    reindex_reason: str | None = None  # why the index was rebuilt; None: the bag's own one
    unread_from: int | None = None  # first byte (B) a rebuilt index could not read past
    unread_reason: str = ""  # what lies there (an incomplete chunk, the index records, ...)
    corrupt_chunks: dict[int, str] = field(default_factory=dict)  # chunk byte -> error
    bad_records: int = 0  # messages unreadable in chunks that did decompress
    lost: Counter[str] = field(default_factory=Counter)  # topic -> messages lost

    @property
    def damaged(self) -> bool:
        return bool(self.reindex_reason or self.corrupt_chunks or self.bad_records)

    def chunk_lost(self, position: int, error: BaseException, counts: dict[str, int]) -> None:
        """A chunk at byte ``position`` could not be read; ``counts``: its messages per topic."""
        self.corrupt_chunks[position] = f"{type(error).__name__}: {error}"
        self.lost.update(counts)

    def record_lost(self, topic: str) -> None:
        """One message record of ``topic`` could not be parsed in a readable chunk."""
        self.bad_records += 1
        self.lost[topic] += 1

    def summary(self) -> str:
        """One line: what was rebuilt, skipped and lost (empty when nothing was)."""
        parts: list[str] = []
        if self.reindex_reason is not None:
            parts.append(
                f"its index is missing or unreadable ({self.reindex_reason}), so it was rebuilt "
                f"from the {self.chunks} complete chunks, as `rosbag reindex` does"
            )
        if self.unread_from is not None:
            parts.append(
                f"the {self.file_bytes - self.unread_from} bytes from byte {self.unread_from} "
                f"of {self.file_bytes} are unreadable ({self.unread_reason}) and were ignored"
            )
        if self.corrupt_chunks:
            shown = sorted(self.corrupt_chunks.items())[:MAX_LISTED]
            where = ", ".join(f"byte {pos}: {err}" for pos, err in shown)
            if len(self.corrupt_chunks) > MAX_LISTED:
                where += ", ..."
            one = len(self.corrupt_chunks) == 1
            parts.append(
                f"{len(self.corrupt_chunks)} of {self.chunks} chunks "
                f"{'is corrupt and was' if one else 'are corrupt and were'} skipped ({where})"
            )
        if self.bad_records:
            parts.append(
                f"{self.bad_records} message record{'' if self.bad_records == 1 else 's'} in "
                "readable chunks could not be parsed"
            )
        total = sum(self.lost.values())
        if total:
            per_topic = ", ".join(f"{n} on {topic}" for topic, n in sorted(self.lost.items()))
            parts.append(f"{total} message{'' if total == 1 else 's'} lost ({per_topic})")
        elif self.corrupt_chunks:
            parts.append("how many messages they held is unknown (no index records for them)")
        return "; ".join(parts)
