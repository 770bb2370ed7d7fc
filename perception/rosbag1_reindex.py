"""Rebuild a ROS1 bag's index from its complete chunks, as ``rosbag reindex`` does.

Why this is written here: rosbags, the project's bag library, refuses a ROS1 bag whose index
is missing or cut off ("Bag is not indexed, reindex before reading") and has no reindex of its
own; the tools that reindex (``rosbag reindex``, the ROS1 C++/Python API) need a ROS
installation, and no well-kept library reads such a bag without one. Yet a recording cut short
by a crash is exactly such a bag, and every chunk it completed is intact. So this module walks
the file's records with rosbags' own record parser (``Header``, ``read_uint32``, its
decompressors) and rebuilds what rosbags' ``Reader.open`` would have read from the index.

ROS1 bag v2.0 layout (http://wiki.ros.org/Bags/Format/2.0): the magic line, the bag header
record, then per chunk a CHUNK record (compressed CONNECTION and MSGDATA records) followed by
one IDXDATA record per connection in it, and at the end the index: CONNECTION and CHUNK_INFO
records. Each record is ``<header length><header><data length><data>``. The walk stops at the
first record that does not fit in the file or cannot be parsed; all before it is kept.
"""

from __future__ import annotations

import os
import struct
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from io import BytesIO
from typing import BinaryIO

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag1,
    MessageDefinition,
    MessageDefinitionFormat,
)
from rosbags.rosbag1 import Reader, ReaderError
from rosbags.rosbag1.reader import (
    Chunk,
    ChunkInfo,
    Header,
    IndexData,
    RecordType,
    decompressors,
    normalize,
    read_uint32,
)
from rosbags.typesys.msg import normalize_msgtype

MAGIC = b"#ROSBAG V2.0\n"
#: What a damaged record or chunk raises in rosbags' parser and the decompressors under it
#: (lz4 raises RuntimeError, bz2 OSError or EOFError; a bad op code ValueError).
RECORD_ERRORS: tuple[type[BaseException], ...] = (
    ReaderError,
    struct.error,
    ValueError,
    KeyError,
    EOFError,
    OSError,
    RuntimeError,
    AssertionError,
)


class NotReindexable(Exception):
    """The file is no bag v2.0 a reindex could read (wrong magic, header or encryption)."""


@dataclass
class Reindexed:
    """What ``Reader.open`` reads from a sound bag's index, rebuilt from the chunks."""

    connections: list[Connection]  # msgcount filled in
    chunk_infos: list[ChunkInfo]  # complete, readable chunks, in file order
    chunks: dict[int, Chunk]  # chunk byte -> where its data lies
    indexes: dict[int, list[IndexData]]  # connection id -> entries sorted by time
    corrupt: dict[int, BaseException] = field(default_factory=dict)  # chunk byte -> error
    lost: Counter[str] = field(default_factory=Counter)  # topic -> messages in corrupt chunks
    unread_from: int | None = None  # first byte not read; None: read to the end
    unread_reason: str = ""


def reindex(bio: BinaryIO, size: int, owner: Reader) -> Reindexed:
    """Walk the records of the bag open in ``bio`` (``size`` B) and rebuild its index.

    ``owner`` becomes the connections' owner (``AnyReader`` groups connections by it).

    Raises:
        NotReindexable: not a ROS1 bag v2.0, or an encrypted one.
    """
    _ = bio.seek(0)
    if bio.readline() != MAGIC:
        raise NotReindexable("the file does not start with '#ROSBAG V2.0'")
    try:
        header = Header.read(bio, RecordType.BAGHEADER)
        padding = read_uint32(bio)
    except RECORD_ERRORS as err:
        raise NotReindexable(f"its bag header is unreadable ({err})") from err
    if header.get("encryptor"):
        raise NotReindexable(f"it is encrypted ({header['encryptor']!r})")
    # Where the index at the end begins (0 while recording): beyond it lies no message.
    index_pos = header.get_uint64("index_pos") if "index_pos" in header else 0
    _ = bio.seek(padding, os.SEEK_CUR)
    walk = _Walk(owner)
    while (pos := bio.tell()) < size:
        op: int | None = None
        try:
            record = Header.read(bio)
            op = record.get_uint8("op")
            datasize = read_uint32(bio)
            if bio.tell() + datasize > size:
                raise ReaderError(f"its {datasize} B of data run past the end of the file")
            datapos = bio.tell()
            if op == RecordType.CHUNK:
                walk.chunk(pos, record, datapos, bio.read(datasize))
            elif op == RecordType.IDXDATA:
                walk.index_data(record)
            elif op == RecordType.CONNECTION:
                _ = bio.seek(datapos - 4)  # the data is a header block with its own length
                walk.connection(record, Header.read(bio))
        except RECORD_ERRORS as err:
            walk.stop(pos, _unread(pos, op, index_pos, err))
            break
        _ = bio.seek(datapos + datasize)
    return walk.result()


def _unread(pos: int, op: int | None, index_pos: int, err: BaseException) -> str:
    """What the unreadable record at byte ``pos`` (of record type ``op``, None if its header
    is unreadable) means for the messages."""
    if op == RecordType.CHUNK:
        return f"an incomplete or damaged chunk, whose messages are lost: {err}"
    if 0 < index_pos <= pos or op in (RecordType.IDXDATA, RecordType.CHUNK_INFO):
        return f"index records, no message lost: {err}"
    return f"an incomplete or damaged record: {err}"


class _Walk:
    """State of one walk over a bag's records."""

    def __init__(self, owner: Reader) -> None:
        self.owner = owner
        self.connections: dict[int, Connection] = {}
        self.entries: dict[int, list[IndexData]] = defaultdict(list)
        self.chunk_infos: list[ChunkInfo] = []
        self.chunks: dict[int, Chunk] = {}
        self.corrupt: dict[int, BaseException] = {}
        self.lost_by_id: Counter[int] = Counter()
        self.last_corrupt: int | None = None  # the IDXDATA records after it count its losses
        self.unread_from: int | None = None
        self.unread_reason = ""

    def stop(self, pos: int, reason: str) -> None:
        self.unread_from, self.unread_reason = pos, reason

    def connection(self, record: Header, data: Header) -> None:
        cid = record.get_uint32("conn")
        if cid in self.connections:
            return  # every connection is written twice: in its first chunk and in the index
        latching = data.get_string("latching") if "latching" in data else ""
        self.connections[cid] = Connection(
            cid,
            normalize(record.get_string("topic")),
            normalize_msgtype(data.get_string("type")),
            MessageDefinition(MessageDefinitionFormat.MSG, data.get_string("message_definition")),
            data.get_string("md5sum"),
            0,
            ConnectionExtRosbag1(
                data.get_string("callerid") if "callerid" in data else None,
                int(latching) if latching else None,
            ),
            self.owner,
        )

    def chunk(self, pos: int, record: Header, datapos: int, data: bytes) -> None:
        """Index the messages of the chunk record at ``pos``, or count it corrupt."""
        self.last_corrupt = None
        entries: list[tuple[int, IndexData]] = []
        try:
            compression = record.get_string("compression")
            if compression not in decompressors:
                raise ReaderError(
                    f"compression {compression!r} is not supported (valid: {sorted(decompressors)})"
                )
            content = decompressors[compression](data)
            src, end = BytesIO(content), len(content)
            while (offset := src.tell()) < end:
                inner = Header.read(src)
                op = inner.get_uint8("op")
                if op == RecordType.CONNECTION:
                    self.connection(inner, Header.read(src))
                    continue
                if op != RecordType.MSGDATA:
                    raise ReaderError(f"a record of op {op} inside a chunk")
                size = read_uint32(src)
                if src.tell() + size > end:
                    raise ReaderError("a message runs past the end of its chunk")
                _ = src.seek(size, os.SEEK_CUR)
                cid = inner.get_uint32("conn")
                entries.append((cid, IndexData(inner.get_time("time"), pos, offset)))
        except RECORD_ERRORS as err:
            self.corrupt[pos] = err
            self.last_corrupt = pos
            return
        counts = Counter(cid for cid, _ in entries)
        times = [e.time for _, e in entries]
        self.chunk_infos.append(
            ChunkInfo(
                pos,
                min(times, default=2**63 - 1),
                max(times) + 1 if times else 0,  # rosbags' end_time is exclusive
                dict(counts),
            )
        )
        self.chunks[pos] = Chunk(len(data), datapos, decompressors[compression])
        for cid, entry in entries:
            self.entries[cid].append(entry)

    def index_data(self, record: Header) -> None:
        """An IDXDATA record: what the chunk before it held, counted lost if it is corrupt."""
        if self.last_corrupt is not None:
            self.lost_by_id[record.get_uint32("conn")] += record.get_uint32("count")

    def result(self) -> Reindexed:
        lost: Counter[str] = Counter()
        for cid, n in self.lost_by_id.items():
            lost[self._topic(cid)] += n
        # Messages whose connection record was in a lost chunk cannot be decoded.
        for cid in [c for c in self.entries if c not in self.connections]:
            lost[self._topic(cid)] += len(self.entries.pop(cid))
        connections = [
            Connection(*c[0:5], len(self.entries.get(c.id, ())), *c[6:])
            for c in sorted(self.connections.values(), key=lambda c: c.id)
        ]
        return Reindexed(
            connections=connections,
            chunk_infos=self.chunk_infos,
            chunks=self.chunks,
            indexes={c.id: sorted(self.entries.get(c.id, [])) for c in connections},
            corrupt=self.corrupt,
            lost=lost,
            unread_from=self.unread_from,
            unread_reason=self.unread_reason,
        )

    def _topic(self, cid: int) -> str:
        conn = self.connections.get(cid)
        return conn.topic if conn else f"connection {cid} (its definition was lost)"
