"""Zip bombs for the tests, written in well under a second: one deflated kernel of zeros, computed
once, stored under many names (a real zip: every member's local header, CRC and sizes are
right, so any unzip tool unpacks it all). `bomb(path, members, mib_each)` with the defaults is the
campaign's bomb: 3.1 MB that unpacks to 3.1 GB."""
from __future__ import annotations

import functools
import struct
import zlib
from pathlib import Path

MiB = 1 << 20


@functools.lru_cache(maxsize=4)
def kernel(mib: int) -> tuple[bytes, int]:
    """(raw deflate of `mib` MiB of zeros, its CRC-32)."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    chunk = bytes(MiB)
    data = b"".join(compressor.compress(chunk) for _ in range(mib)) + compressor.flush()
    crc = 0
    for _ in range(mib):
        crc = zlib.crc32(chunk, crc)
    return data, crc


def bomb(path: Path, members: int = 31, mib_each: int = 100, extra: dict[str, bytes] | None = None,
         prefix: str = "resources/bomb") -> Path:
    """A zip of `members` members of `mib_each` MiB of zeros each (plus `extra` files, stored)."""
    data, crc = kernel(mib_each)
    size = mib_each * MiB
    entries = [(f"{prefix}{i:03d}.bin".encode(), 8, data, crc, size) for i in range(members)]
    entries += [(name.encode(), 0, content, zlib.crc32(content), len(content)) for name, content in (extra or {}).items()]
    body, central = bytearray(), bytearray()
    for name, method, payload, crc32, length in entries:
        offset = len(body)
        body += struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, method, 0, 0, crc32, len(payload), length, len(name), 0)
        body += name + payload
        central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, method, 0, 0, crc32, len(payload), length,
                               len(name), 0, 0, 0, 0, 0, offset)
        central += name
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries), len(central), len(body), 0)
    path.write_bytes(bytes(body + central + end))
    return path
