"""A rosbags ROS1 reader that reads what is intact in a damaged bag and accounts for the rest.

``RecoveringReader`` is rosbags' ``rosbag1.Reader`` with two changes:

- ``open``: a bag whose index is missing, cut off or unreadable (a recording cut short by a
  crash, a partial copy) has its index rebuilt from its complete chunks
  (``perception.rosbag1_reindex``) instead of being refused.
- ``messages``: a chunk that does not decompress (a corrupt LZ4 or bz2 chunk) or a message
  record that does not parse is skipped instead of ending the iteration with the library's
  exception.

What was rebuilt, skipped and lost is kept in ``damage`` (``perception.bag_damage``);
``read_bag`` decides whether what is left is enough. ``AnyReader`` uses it in place of its
own ROS1 reader, so typestores and deserialization stay rosbags'.
"""

from __future__ import annotations

import heapq
import os
from collections.abc import Collection, Generator
from io import BytesIO
from pathlib import Path
from typing import BinaryIO

from rosbags.interfaces import Connection
from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import Header, IndexData, RecordType, read_bytes, read_uint32

from perception.bag_damage import BagDamage
from perception.rosbag1_reindex import RECORD_ERRORS, NotReindexable, reindex


class RecoveringReader(Reader):
    """rosbags' ROS1 reader, tolerant of corrupt chunks and of a missing or cut index."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.damage = BagDamage(file_bytes=self.path.stat().st_size)

    def open(self) -> None:
        """Open the bag, rebuilding its index from the chunks if it cannot be read.

        Raises:
            ReaderError (or what rosbags raises): not a ROS1 bag v2.0, an encrypted one, or
                one without a single complete chunk.
        """
        try:
            super().open()
        except RECORD_ERRORS as err:
            # rosbags closed the file on failure; reopen it to walk the records.
            self._rebuild_index(err)
        self.damage.chunks = len(self.chunk_infos) + len(self.damage.corrupt_chunks)

    def _rebuild_index(self, err: BaseException) -> None:
        bio = self.path.open("rb")
        try:
            index = reindex(bio, self.damage.file_bytes, self)
        except NotReindexable:
            bio.close()
            raise err from None
        except BaseException:
            bio.close()
            raise
        if not index.chunk_infos:
            bio.close()
            where = (
                f"; from byte {index.unread_from} on: {index.unread_reason}"
                if index.unread_from is not None
                else ""
            )
            corrupt = f"; {len(index.corrupt)} corrupt" if index.corrupt else ""
            raise ReaderError(
                f"{err}; rebuilding the index found no complete, readable chunk{corrupt}{where}"
            ) from err
        self.bio = bio
        self.connections = index.connections
        self.chunk_infos = index.chunk_infos
        self.chunks = index.chunks
        self.indexes = index.indexes
        self.damage.reindex_reason = f"{type(err).__name__}: {err}"
        self.damage.unread_from = index.unread_from
        self.damage.unread_reason = index.unread_reason
        for pos, error in index.corrupt.items():
            self.damage.chunk_lost(pos, error, {})
        self.damage.lost.update(index.lost)

    def messages(
        self,
        connections: Collection[Connection] = (),
        start: int | None = None,
        stop: int | None = None,
    ) -> Generator[tuple[Connection, int, bytes], None, None]:
        """(connection, log time ns, raw message) in time order, as rosbags' ``messages``.

        Messages in corrupt chunks, and records that do not parse, are skipped and counted in
        ``damage``. (rosbags' own loop, re-written because it stops at the first bad chunk.)
        """
        self._check_open()
        wanted = list(connections) or self.connections
        connmap = {c.id: c for c in self.connections}
        streams = [[(entry, c) for entry in self.indexes[c.id]] for c in wanted]
        for entry, conn in heapq.merge(*streams, key=lambda pair: pair[0].time):
            if start is not None and entry.time < start:
                continue
            if stop is not None and entry.time >= stop:
                return
            chunk = self._chunk(entry.chunk_pos, connmap)
            if chunk is None:
                continue  # counted when the chunk was found corrupt
            try:
                data = _message_at(chunk, entry, conn)
            except RECORD_ERRORS:
                self.damage.record_lost(conn.topic)
                continue
            yield conn, entry.time, data

    def _chunk(self, pos: int, connmap: dict[int, Connection]) -> BinaryIO | None:
        """The decompressed chunk at byte ``pos``, or None if it is corrupt."""
        if pos in self.damage.corrupt_chunks:
            return None
        if self.current_chunk[0] == pos:
            return self.current_chunk[1]
        assert self.bio is not None  # _check_open
        header = self.chunks[pos]
        try:
            _ = self.bio.seek(header.datapos)
            raw = header.decompressor(read_bytes(self.bio, header.datasize))
        except RECORD_ERRORS as err:
            info = next(c for c in self.chunk_infos if c.pos == pos)
            counts = {
                connmap[cid].topic if cid in connmap else f"connection {cid}": n
                for cid, n in info.connection_counts.items()
            }
            self.damage.chunk_lost(pos, err, counts)
            return None
        self.current_chunk[1].close()
        self.current_chunk = (pos, BytesIO(raw))
        return self.current_chunk[1]


def _message_at(chunk: BinaryIO, entry: IndexData, conn: Connection) -> bytes:
    """The raw message of the MSGDATA record the index entry points to in its chunk."""
    _ = chunk.seek(entry.offset)
    while True:
        header = Header.read(chunk)
        op = header.get_uint8("op")
        if op != RecordType.CONNECTION:
            break
        _ = chunk.seek(read_uint32(chunk), os.SEEK_CUR)
    if op != RecordType.MSGDATA:
        raise ReaderError(f"expected a message record at offset {entry.offset}, found op {op}")
    if header.get_uint32("conn") != conn.id or header.get_time("time") != entry.time:
        raise ReaderError(f"the message record at offset {entry.offset} disagrees with the index")
    return read_bytes(chunk, read_uint32(chunk))
