"""A minimal reader of a .usdc file's value reps, written for tests from the
crate format as usd-core lays it out (crateFile.cpp): which 8-byte rep each
field of each spec holds, so a test can compare how painterly and usd-core
encode the same value (inlined or stored, array, compressed, where) rather
than only what the value reads back as.

Reads the table of contents and the TOKENS, FIELDS, FIELDSETS, PATHS and
SPECS sections (LZ4 blocks in usd-core's chunk framing, index lists
integer-coded before that). Values themselves are not decoded.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

ARRAY = 1 << 63
INLINED = 1 << 62
COMPRESSED = 1 << 61
PAYLOAD_MASK = (1 << 48) - 1
DICTIONARY = 31  # the crate type enum (crateDataTypes.h)


@dataclass(frozen=True)
class Rep:
    bits: int

    @property
    def type(self) -> int:
        return (self.bits >> 48) & 0xFF

    @property
    def array(self) -> bool:
        return bool(self.bits & ARRAY)

    @property
    def inlined(self) -> bool:
        return bool(self.bits & INLINED)

    @property
    def compressed(self) -> bool:
        return bool(self.bits & COMPRESSED)

    @property
    def payload(self) -> int:
        return self.bits & PAYLOAD_MASK


def _extended_length(src: bytes, i: int, n: int) -> tuple[int, int]:
    """A 4-bit length of 15 continues in the next bytes, each added, until
    one is not 255. Returns the length and the index after it."""
    if n == 15:
        while True:
            b = src[i]
            i += 1
            n += b
            if b != 255:
                break
    return n, i


def lz4_block(src: bytes) -> bytes:
    """One LZ4 block (the raw block format, no frame header)."""
    out = bytearray()
    i = 0
    while i < len(src):
        token = src[i]
        i += 1
        n, i = _extended_length(src, i, token >> 4)
        out += src[i:i + n]
        i += n
        if i >= len(src):
            break  # the last sequence has literals only
        offset = src[i] | (src[i + 1] << 8)
        i += 2
        m, i = _extended_length(src, i, token & 15)
        start = len(out) - offset
        for k in range(m + 4):  # matches may overlap what they produce
            out.append(out[start + k])
    return bytes(out)


def fast_decompress(src: bytes) -> bytes:
    """usd-core's TfFastCompression framing: a chunk count byte (0: one
    block, no size), else per chunk an i32 size and a block."""
    chunks = src[0]
    if chunks == 0:
        return lz4_block(src[1:])
    out, i = bytearray(), 1
    for _ in range(chunks):
        (size,) = struct.unpack_from("<i", src, i)
        i += 4
        out += lz4_block(src[i:i + size])
        i += size
    return bytes(out)


def decode_ints32(data: bytes, n: int) -> list[int]:
    """Sdf_IntegerCompression for 32-bit ints: the common difference, 2-bit
    codes, then the other differences at 8/16/32 bits; summed back."""
    if n == 0:
        return []
    (common,) = struct.unpack_from("<i", data, 0)
    codes_at = 4
    at = codes_at + (2 * n + 7) // 8
    out, prev = [], 0
    for k in range(n):
        code = (data[codes_at + k // 4] >> (2 * (k % 4))) & 3
        if code == 0:
            d = common
        else:
            fmt, size = {1: ("<b", 1), 2: ("<h", 2), 3: ("<i", 4)}[code]
            (d,) = struct.unpack_from(fmt, data, at)
            at += size
        prev = (prev + d + 2**31) % 2**32 - 2**31
        out.append(prev)
    return out


class Crate:
    def __init__(self, path):
        with open(path, "rb") as f:
            self.data = f.read()
        assert self.data[:8] == b"PXR-USDC", f"{path}: not a crate file"
        (toc,) = struct.unpack_from("<Q", self.data, 16)
        (count,) = struct.unpack_from("<Q", self.data, toc)
        self.sections = {}
        for k in range(count):
            name, start, size = struct.unpack_from("<16sQQ", self.data, toc + 8 + 32 * k)
            self.sections[name.rstrip(b"\0").decode()] = (start, size)
        self._read_tokens()
        self._read_fields()
        self._read_fieldsets()
        self._read_paths()
        self._read_specs()

    def _u64(self, at: int) -> int:
        return struct.unpack_from("<Q", self.data, at)[0]

    def _ints(self, at: int, n: int) -> tuple[list[int], int]:
        """A compressed index list at `at`: its byte size, then the bytes."""
        size = self._u64(at)
        ints = decode_ints32(fast_decompress(self.data[at + 8:at + 8 + size]), n)
        return ints, at + 8 + size

    def _read_tokens(self):
        at, _ = self.sections["TOKENS"]
        n, _raw, size = struct.unpack_from("<QQQ", self.data, at)
        text = fast_decompress(self.data[at + 24:at + 24 + size])
        self.tokens = text.split(b"\0")[:n]
        self.tokens = [t.decode() for t in self.tokens]

    def _read_fields(self):
        at, _ = self.sections["FIELDS"]
        n = self._u64(at)
        self.field_tokens, at = self._ints(at + 8, n)
        size = self._u64(at)
        raw = fast_decompress(self.data[at + 8:at + 8 + size])
        self.field_reps = [Rep(b) for b in struct.unpack_from(f"<{n}Q", raw)]

    def _read_fieldsets(self):
        at, _ = self.sections["FIELDSETS"]
        n = self._u64(at)
        self.fieldsets, _ = self._ints(at + 8, n)

    def _read_paths(self):
        at, _ = self.sections["PATHS"]
        n = self._u64(at)
        encoded = self._u64(at + 8)
        index, at = self._ints(at + 16, encoded)
        element, at = self._ints(at, encoded)
        jumps, _ = self._ints(at, encoded)
        self.paths = [""] * n
        # Depth first: a jump of -1 means a child only, 0 a sibling only
        # (next), > 0 both (the sibling that far on), -2 neither.
        stack = [(0, None)]
        while stack:
            k, parent = stack.pop()
            while True:
                if parent is None:
                    path = "/"
                else:
                    tok = element[k]
                    name = self.tokens[abs(tok)]
                    if tok < 0:
                        path = f"{parent}.{name}"
                    else:
                        path = f"/{name}" if parent == "/" else f"{parent}/{name}"
                self.paths[index[k]] = path
                j = jumps[k]
                has_child, has_sibling = j > 0 or j == -1, j >= 0
                if has_child and has_sibling:
                    stack.append((k + j, parent))
                if has_child:
                    parent = path
                elif not has_sibling:
                    break
                k += 1

    def _read_specs(self):
        at, _ = self.sections["SPECS"]
        n = self._u64(at)
        paths, at = self._ints(at + 8, n)
        fieldsets, at = self._ints(at, n)
        self.specs = {}
        for p, fs in zip(paths, fieldsets):
            fields = {}
            while self.fieldsets[fs] != -1:
                f = self.fieldsets[fs]
                fields[self.tokens[self.field_tokens[f]]] = self.field_reps[f]
                fs += 1
            self.specs[self.paths[p]] = fields

    def rep(self, spec: str, field: str) -> Rep:
        return self.specs[spec][field]

    def dictionary_reps(self, rep: Rep) -> list[Rep]:
        """The reps of a stored dictionary's values, in key order: after the
        count, per entry a string index and the value nested (usd-core's
        `Write(VtValue)`: a jump over what it stores, then its rep)."""
        assert rep.type == DICTIONARY and not rep.inlined, rep
        at = rep.payload
        n = self._u64(at)
        at += 8
        reps = []
        for _ in range(n):
            at += 4
            (jump,) = struct.unpack_from("<q", self.data, at)
            at += jump
            reps.append(Rep(self._u64(at)))
            at += 8
        return reps
