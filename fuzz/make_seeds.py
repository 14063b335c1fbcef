#!/usr/bin/env python3
"""Writes the generated seeds of fuzz/corpus/ (TIFF and STL); see docs/fuzzing.md.

The TIFF files are built byte by byte here (no imaging library needed): 8-,
16- and 32-bit unsigned, 16-bit signed, 32- and 64-bit float; strips and
tiles (with padded edge tiles); no compression, deflate, PackBits and LZW;
horizontal and floating-point predictors; little- and big-endian; classic
TIFF and BigTIFF; plus an RGB and a MinIsWhite image that xgauge refuses.
The STL files are a tetrahedron and a cube, ASCII and binary, an inward one,
two solids in one file and a cube with a corner written 1e-13 mm off (welded).
Deterministic: running it again gives the same bytes. Usage:
    python3 fuzz/make_seeds.py            # writes fuzz/corpus/{tiff,stl}
"""
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))

# TIFF ---------------------------------------------------------------------

SHORT, LONG, DOUBLE, LONG8 = 3, 4, 12, 16
TYPE_SIZE = {SHORT: 2, LONG: 4, DOUBLE: 8, LONG8: 8}
TYPE_CHAR = {SHORT: "H", LONG: "I", DOUBLE: "d", LONG8: "Q"}
UINT, INT, IEEEFP = 1, 2, 3


def sample_format_char(bits, fmt):
    if fmt == IEEEFP:
        return {32: "f", 64: "d"}[bits]
    chars = {8: "B", 16: "H", 32: "I"}
    c = chars[bits]
    return c.lower() if fmt == INT else c


def packbits(row):
    """PackBits: a repeat run for leading equal bytes, literal runs for the rest."""
    out = bytearray()
    i = 0
    while i < len(row):
        run = 1
        while i + run < len(row) and run < 128 and row[i + run] == row[i]:
            run += 1
        if run >= 3:
            out += struct.pack("b", -(run - 1)) + bytes([row[i]])
            i += run
            continue
        n = min(128, len(row) - i)
        out += struct.pack("b", n - 1) + row[i:i + n]
        i += n
    return bytes(out)


def lzw(data):
    """TIFF LZW (MSB-first codes, 9 bits); inputs stay below 510 table entries."""
    table = {bytes([i]): i for i in range(256)}
    next_code = 258
    codes = [256]
    w = b""
    for c in data:
        wc = w + bytes([c])
        if wc in table:
            w = wc
            continue
        codes.append(table[w])
        table[wc] = next_code
        next_code += 1
        w = bytes([c])
    if w:
        codes.append(table[w])
    codes.append(257)
    assert next_code < 510, "keep LZW seeds small: 9-bit codes only"
    bits = "".join(format(code, "09b") for code in codes)
    bits += "0" * (-len(bits) % 8)
    return bytes(int(bits[i:i + 8], 2) for i in range(0, len(bits), 8))


def encode_rows(rows, bits, fmt, predictor, order):
    """Bytes of a strip or tile (list of rows of values) before compression."""
    out = bytearray()
    char = sample_format_char(bits, fmt)
    for row in rows:
        if predictor == 2:  # horizontal differencing, modulo 2^bits
            mask = (1 << bits) - 1
            row = [row[0]] + [(row[i] - row[i - 1]) & mask for i in range(1, len(row))]
            char = char.upper()
        if predictor == 3:  # floating point: byte planes (most significant first), then differences
            nbytes = bits // 8
            be = b"".join(struct.pack(">" + char, v) for v in row)
            planes = bytearray(len(be))
            for i in range(len(row)):
                for b in range(nbytes):
                    planes[b * len(row) + i] = be[i * nbytes + b]
            for i in range(len(planes) - 1, 0, -1):
                planes[i] = (planes[i] - planes[i - 1]) & 0xFF
            out += planes
        else:
            out += struct.pack(order + char * len(row), *row)
    return bytes(out)


def compress(raw, compression, row_bytes):
    if compression == 1:
        return raw
    if compression == 8:
        return zlib.compress(raw, 9)
    if compression == 32773:
        return b"".join(packbits(raw[i:i + row_bytes]) for i in range(0, len(raw), row_bytes))
    if compression == 5:
        return lzw(raw)
    raise ValueError(compression)


def tiff(width, height, bits, fmt, pixel, compression=1, predictor=1, tile=None,
         rows_per_strip=None, big_endian=False, bigtiff=False, photometric=1, spp=1):
    order = ">" if big_endian else "<"
    image = [[pixel(x, y) for x in range(width * spp)] for y in range(height)]
    chunks = []
    if tile:
        tw, th = tile
        for ty in range(0, height, th):
            for tx in range(0, width, tw):
                rows = []
                for y in range(ty, ty + th):
                    row = [image[y][x] if y < height and x < width else 0
                           for x in range(tx, tx + tw)]
                    rows.append(row)
                raw = encode_rows(rows, bits, fmt, predictor, order)
                chunks.append(compress(raw, compression, tw * bits // 8))
    else:
        rps = rows_per_strip or height
        for y0 in range(0, height, rps):
            raw = encode_rows(image[y0:y0 + rps], bits, fmt, predictor, order)
            chunks.append(compress(raw, compression, width * spp * bits // 8))

    header_size = 16 if bigtiff else 8
    data = bytearray()
    offsets = []
    for c in chunks:
        offsets.append(header_size + len(data))
        data += c
        if len(data) % 2:
            data += b"\0"
    offset_type = LONG8 if bigtiff else LONG
    entries = {
        256: (LONG, [width]), 257: (LONG, [height]), 258: (SHORT, [bits] * spp),
        259: (SHORT, [compression]), 262: (SHORT, [photometric]), 277: (SHORT, [spp]),
        284: (SHORT, [1]), 339: (SHORT, [fmt] * spp),
    }
    if predictor != 1:
        entries[317] = (SHORT, [predictor])
    if tile:
        entries[322] = (LONG, [tile[0]])
        entries[323] = (LONG, [tile[1]])
        entries[324] = (offset_type, offsets)
        entries[325] = (offset_type, [len(c) for c in chunks])
    else:
        entries[273] = (offset_type, offsets)
        entries[278] = (LONG, [rows_per_strip or height])
        entries[279] = (offset_type, [len(c) for c in chunks])

    ifd_offset = header_size + len(data)
    entry_size, count_size, inline = (20, 8, 8) if bigtiff else (12, 2, 4)
    ifd_size = count_size + entry_size * len(entries) + inline
    extra = bytearray()
    ifd = bytearray(struct.pack(order + ("Q" if bigtiff else "H"), len(entries)))
    for tag in sorted(entries):
        typ, values = entries[tag]
        payload = struct.pack(order + TYPE_CHAR[typ] * len(values), *values)
        ifd += struct.pack(order + "HH", tag, typ)
        ifd += struct.pack(order + ("Q" if bigtiff else "I"), len(values))
        if len(payload) <= inline:
            ifd += payload + b"\0" * (inline - len(payload))
        else:
            where = ifd_offset + ifd_size + len(extra)
            ifd += struct.pack(order + ("Q" if bigtiff else "I"), where)
            extra += payload
            if len(extra) % 2:
                extra += b"\0"
    ifd += b"\0" * inline  # no next IFD
    assert len(ifd) == ifd_size
    magic = b"MM" if big_endian else b"II"
    if bigtiff:
        header = magic + struct.pack(order + "HHHQ", 43, 8, 0, ifd_offset)
    else:
        header = magic + struct.pack(order + "HI", 42, ifd_offset)
    return bytes(header + data + ifd + extra)


def ramp(scale, offset=0):
    return lambda x, y: (x * 7 + y * 13) % scale + offset


def tiff_seeds():
    smooth = lambda x, y: 0.25 + 0.5 * math.sin(x * 0.3) * math.cos(y * 0.2)
    return {
        "u8_strips.tif": tiff(16, 16, 8, UINT, ramp(256), rows_per_strip=4),
        "u16_deflate_predictor2.tif": tiff(24, 20, 16, UINT, ramp(65536, 1000), compression=8,
                                           predictor=2, rows_per_strip=8),
        "u16_big_endian_packbits.tif": tiff(16, 12, 16, UINT, lambda x, y: 0 if x < 8 else x * y,
                                            compression=32773, big_endian=True, rows_per_strip=5),
        "u16_tiled_edges.tif": tiff(20, 20, 16, UINT, ramp(60000), tile=(16, 16)),
        "u32.tif": tiff(8, 8, 32, UINT, lambda x, y: (x << 20) + y * 3),
        "i16_refused.tif": tiff(8, 8, 16, INT, lambda x, y: x - y),
        "f32_big_endian.tif": tiff(16, 16, 32, IEEEFP, smooth, big_endian=True, rows_per_strip=3),
        "f32_tiled_deflate_predictor3.tif": tiff(40, 36, 32, IEEEFP, smooth, compression=8,
                                                 predictor=3, tile=(16, 16)),
        "f64_deflate.tif": tiff(8, 8, 64, IEEEFP, smooth, compression=8),
        "u8_lzw.tif": tiff(12, 12, 8, UINT, ramp(64), compression=5),
        "u8_bigtiff_deflate.tif": tiff(16, 8, 8, UINT, ramp(256), compression=8, bigtiff=True),
        "rgb_refused.tif": tiff(4, 4, 8, UINT, ramp(256), photometric=2, spp=3),
        "miniswhite_refused.tif": tiff(4, 4, 8, UINT, ramp(256), photometric=0),
    }

# STL ----------------------------------------------------------------------

TETRA = ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)],
         [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
CUBE_V = [(-10 if i & 1 == 0 else 10, -15 if i & 2 == 0 else 15, -5 if i & 4 == 0 else 5)
          for i in range(8)]
CUBE_T = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
          (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]


def soup(mesh, flip=False, offset=(0, 0, 0)):
    vertices, triangles = mesh
    out = []
    for t in triangles:
        t = (t[0], t[2], t[1]) if flip else t
        out.append([tuple(vertices[i][k] + offset[k] for k in range(3)) for i in t])
    return out


def ascii_stl(triangles, name="part", fmt="{:g}"):
    lines = ["solid " + name]
    for corners in triangles:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += ["      vertex " + " ".join(fmt.format(c) for c in corner) for corner in corners]
        lines += ["    endloop", "  endfacet"]
    lines.append("endsolid " + name)
    return "\n".join(lines) + "\n"


def binary_stl(triangles):
    out = bytearray(b"binary STL seed".ljust(80, b" "))
    out += struct.pack("<I", len(triangles))
    for corners in triangles:
        out += struct.pack("<3f", 0, 0, 0)
        for corner in corners:
            out += struct.pack("<3f", *corner)
        out += b"\0\0"
    return bytes(out)


def stl_seeds():
    cube_near = soup((CUBE_V, CUBE_T))
    cube_near[5][1] = (cube_near[5][1][0] + 1e-13,) + cube_near[5][1][1:]
    return {
        "tetra_ascii.stl": ascii_stl(soup(TETRA), "tetra").encode(),
        "tetra_binary.stl": binary_stl(soup(TETRA)),
        "tetra_inward_ascii.stl": ascii_stl(soup(TETRA, flip=True), "inward").encode(),
        "cube_ascii.stl": ascii_stl(soup((CUBE_V, CUBE_T)), "cube").encode(),
        "cube_binary.stl": binary_stl(soup((CUBE_V, CUBE_T))),
        "cube_near_weld_ascii.stl": ascii_stl(cube_near, "near", "{:.17e}").encode(),
        "two_solids_ascii.stl": (ascii_stl(soup(TETRA), "a") +
                                 ascii_stl(soup(TETRA, offset=(5, 0, 0)), "b")).encode(),
    }


def main():
    for folder, seeds in (("tiff", tiff_seeds()), ("stl", stl_seeds())):
        path = os.path.join(HERE, "corpus", "fuzz_" + folder)
        os.makedirs(path, exist_ok=True)
        for name, data in sorted(seeds.items()):
            assert len(data) < 20 * 1024, name
            with open(os.path.join(path, name), "wb") as f:
                f.write(data)
            print(f"{os.path.relpath(os.path.join(path, name))}: {len(data)} bytes")


if __name__ == "__main__":
    main()
