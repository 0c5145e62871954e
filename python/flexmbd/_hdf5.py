"""Checks of HDF5 files before HDF5 reads them, shared by the readers of body files
(:mod:`flexmbd.fe.body_file`) and results files (:mod:`flexmbd.results_file`)."""

from __future__ import annotations

import mmap
import os
import struct

#: The signature of an HDF5 file (the start of its superblock).
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

#: The signature and version (1) of a global heap collection.
HEAP_SIGNATURE = b"GCOL\x01\x00\x00\x00"


def global_heap_damage(path: str | os.PathLike[str]) -> str | None:
    """What is wrong with a global heap collection of the HDF5 file `path`, or None.

    HDF5 keeps variable-length strings (the ``type`` attributes and string fields of a body
    file, the root attributes of a results file) in global heap collections, which have no
    checksum and which HDF5 does not check: reading a string from a collection whose size
    runs past the end of the file (a truncated file) or whose objects do not fit it (a
    flipped byte) loops for ever or crashes the process. So they are checked first, found by
    their signature: the collection must lie in the file, and its objects (16-byte headers,
    data padded to 8 bytes) must end at its free space (object 0), exactly at the end of the
    collection, or leave a tail shorter than a header. Files whose superblock is not at byte
    0 or whose size of lengths is not 8 bytes (not written by h5py's defaults) are not
    checked. A file that cannot be read gives a message too."""
    try:
        with open(path, "rb") as file, mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ) as data:
            version = data[8] if len(data) > 16 else -1
            lengths = data[14] if version in (0, 1) else data[10] if version in (2, 3) else 0
            if data[:8] != HDF5_SIGNATURE or lengths != 8:
                return None
            start = data.find(HEAP_SIGNATURE)
            while start >= 0:
                (size,) = (
                    struct.unpack_from("<Q", data, start + 8) if start + 16 <= len(data) else (0,)
                )
                end = start + size
                if size < 16 or size % 8 or end > len(data):
                    return (
                        f"a global heap collection at byte {start} has the size {size}; the file "
                        f"has {len(data)} bytes"
                    )
                position = start + 16
                while position + 16 <= end:
                    index, _, _, object_size = struct.unpack_from("<HHIQ", data, position)
                    if index == 0:
                        intact = position + object_size == end
                        break
                    position += 16 + (object_size + 7) // 8 * 8
                else:
                    intact = 0 <= end - position < 16
                if not intact:
                    return (
                        f"the objects of the global heap collection at byte {start} do not fit it"
                    )
                start = data.find(HEAP_SIGNATURE, end)
    except (OSError, ValueError) as error:
        return f"it cannot be read: {error}"
    return None
