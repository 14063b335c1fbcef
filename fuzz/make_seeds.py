#!/usr/bin/env python3
"""Writes the generated seeds of fuzz/corpus/ (TIFF, raw, DICOM and STL; NXtomo
with --xgauge); see docs/fuzzing.md.

The TIFF files are built byte by byte here (no imaging library needed): 8-,
16- and 32-bit unsigned, 16-bit signed, 32- and 64-bit float; strips and
tiles (with padded edge tiles); no compression, deflate, PackBits and LZW;
horizontal and floating-point predictors; little- and big-endian; classic
TIFF and BigTIFF; plus an RGB and a MinIsWhite image that xgauge refuses.
The STL files are a tetrahedron and a cube, ASCII and binary, an inward one,
two solids in one file and a cube with a corner written 1e-13 mm off (welded).
The raw seeds are a sidecar length (2 bytes), a JSON or INI sidecar and the
samples (fuzz/fuzz_raw.cpp); the DICOM files are built byte by byte (explicit
and implicit VR little-endian, big-endian, 8- and 16-bit, two frames, a
rescale, float pixel data, and an RLE transfer syntax xgauge refuses). NXtomo
needs libhdf5: with --xgauge PATH, `PATH convert` writes those seeds from
TIFF seeds (uint16 and float32).
Deterministic: running it again gives the same bytes. Usage:
    python3 fuzz/make_seeds.py [--xgauge build/apps/xgauge/xgauge]
"""
import math
import os
import struct
import subprocess
import sys
import tempfile
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


# Raw + sidecar --------------------------------------------------------------

def raw_seed(sidecar, samples):
    return struct.pack("<H", len(sidecar)) + sidecar + samples


def raw_seeds():
    u16 = b"".join(struct.pack("<H", 100 * i) for i in range(12))
    f32_be = b"".join(struct.pack(">f", 0.25 * i) for i in range(12))
    json_u16 = b'{"width": 4, "height": 3, "type": "uint16", "byte_order": "little"}'
    ini_f32 = (b"[raw]\nwidth = 3\nheight = 2\ntype = float32\nbyte_order = big\n"
               b"offset = 4\nframes = 2\n")
    return {
        "u16_json.bin": raw_seed(json_u16, u16),
        "f32_big_ini_offset_frames.bin": raw_seed(ini_f32, b"HEAD" + f32_be[:48]),
        "u8_json.bin": raw_seed(b'{"width": 3, "height": 2, "type": "uint8"}', bytes(range(6))),
        "f64_json_nan.bin": raw_seed(
            b'{"width": 1, "height": 2, "type": "float64", "byte_order": "little"}',
            struct.pack("<2d", 1.0, float("nan"))),
    }


# DICOM ----------------------------------------------------------------------

LONG_VRS = {b"OB", b"OW", b"OF", b"SQ", b"UT", b"UN"}


def dicom_element(group, element, vr, value, explicit=True, big=False):
    if len(value) % 2:
        value += b"\0" if vr in (b"UI", b"OB") else b" "
    order = ">" if big else "<"
    tag = struct.pack(order + "HH", group, element)
    if not explicit:
        return tag + struct.pack(order + "I", len(value)) + value
    if vr in LONG_VRS:
        return tag + vr + b"\0\0" + struct.pack(order + "I", len(value)) + value
    return tag + vr + struct.pack(order + "H", len(value)) + value


def dicom(width, height, bits=16, frames=1, syntax=b"1.2.840.10008.1.2.1", rescale=None,
          float_pixels=False):
    explicit = syntax != b"1.2.840.10008.1.2"
    big = syntax == b"1.2.840.10008.1.2.2"
    order = ">" if big else "<"
    meta_body = (dicom_element(2, 1, b"OB", b"\0\1") +
                 dicom_element(2, 2, b"UI", b"1.2.840.10008.5.1.4.1.1.1.1.1") +
                 dicom_element(2, 3, b"UI", b"2.25.1") +
                 dicom_element(2, 0x10, b"UI", syntax) +
                 dicom_element(2, 0x12, b"UI", b"2.25.2"))
    meta = dicom_element(2, 0, b"UL", struct.pack("<I", len(meta_body))) + meta_body

    def el(group, element, vr, value):
        return dicom_element(group, element, vr, value, explicit, big)

    def us(value):
        return struct.pack(order + "H", value)
    data = el(8, 0x60, b"CS", b"DX")
    data += el(0x28, 2, b"US", us(1)) + el(0x28, 4, b"CS", b"MONOCHROME2")
    if frames > 1:
        data += el(0x28, 8, b"IS", str(frames).encode())
    data += el(0x28, 0x10, b"US", us(height)) + el(0x28, 0x11, b"US", us(width))
    data += el(0x28, 0x100, b"US", us(32 if float_pixels else bits))
    if not float_pixels:
        data += el(0x28, 0x101, b"US", us(bits)) + el(0x28, 0x102, b"US", us(bits - 1))
        data += el(0x28, 0x103, b"US", us(0))
    if rescale:
        data += el(0x28, 0x1052, b"DS", rescale[1]) + el(0x28, 0x1053, b"DS", rescale[0])
    n = width * height * frames
    if float_pixels:
        data += el(0x7FE0, 8, b"OF", struct.pack(order + "%df" % n, *[0.5 * i for i in range(n)]))
    elif bits == 8:
        data += el(0x7FE0, 0x10, b"OB", bytes(i % 256 for i in range(n)))
    else:
        data += el(0x7FE0, 0x10, b"OW", struct.pack(order + "%dH" % n, *[97 * i for i in range(n)]))
    return b"\0" * 128 + b"DICM" + meta + data


def dicom_seeds():
    return {
        "u16_explicit_le.dcm": dicom(7, 5),
        "u16_implicit_le.dcm": dicom(4, 3, syntax=b"1.2.840.10008.1.2"),
        "u16_big_endian.dcm": dicom(4, 3, syntax=b"1.2.840.10008.1.2.2"),
        "u8_two_frames.dcm": dicom(5, 3, bits=8, frames=2),
        "u16_rescaled.dcm": dicom(4, 4, rescale=(b"0.5", b"-10")),
        "f32_float_pixel_data.dcm": dicom(3, 3, float_pixels=True),
        "rle_refused.dcm": dicom(4, 3, syntax=b"1.2.840.10008.1.2.5"),
    }


def nxtomo_seeds(xgauge):
    """NXtomo files written by `xgauge convert` from two TIFF seeds."""
    seeds = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, data in (("u16", tiff(6, 4, 16, UINT, ramp(4000))),
                           ("f32", tiff(5, 3, 32, IEEEFP, lambda x, y: 0.5 + 0.1 * x - y))):
            tif = os.path.join(folder, name + ".tif")
            with open(tif, "wb") as f:
                f.write(data)
            nxs = os.path.join(folder, name + ".nxs")
            subprocess.run([xgauge, "convert", tif, nxs, "-q"], check=True)
            with open(nxs, "rb") as f:
                seeds[name + "_projection.nxs"] = f.read()
    return seeds


def main():
    sets = [("tiff", tiff_seeds()), ("raw", raw_seeds()), ("diconde", dicom_seeds()),
            ("stl", stl_seeds())]
    if "--xgauge" in sys.argv:
        sets.append(("nxtomo", nxtomo_seeds(sys.argv[sys.argv.index("--xgauge") + 1])))
    for folder, seeds in sets:
        path = os.path.join(HERE, "corpus", "fuzz_" + folder)
        os.makedirs(path, exist_ok=True)
        for name, data in sorted(seeds.items()):
            assert len(data) < 20 * 1024, name
            with open(os.path.join(path, name), "wb") as f:
                f.write(data)
            print(f"{os.path.relpath(os.path.join(path, name))}: {len(data)} bytes")


if __name__ == "__main__":
    main()
