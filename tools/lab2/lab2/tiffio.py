"""TIFF reading and writing (tifffile).

Written: raw frames as 16-bit unsigned with deflate and the horizontal
predictor (as xgauge writes its raw shots); float32 images with deflate and
no predictor (tifffile needs the optional imagecodecs package for the
floating-point predictor, which Debian's python3-tifffile does not pull in).
Read: anything tifffile reads, and float TIFFs with the floating-point
predictor (TIFF Technical Note 3, as xgauge writes them) decoded here.
"""

import os
import zlib

import numpy as np
import tifffile


def write_u16(path, img):
    a = np.asarray(img)
    if a.dtype != np.uint16:
        a = np.clip(np.rint(a), 0, 65535).astype(np.uint16)
    _atomic(path, lambda p: tifffile.imwrite(p, a, compression="zlib", predictor=True, photometric="minisblack"))


def write_f32(path, img):
    a = np.asarray(img, dtype=np.float32)
    _atomic(path, lambda p: tifffile.imwrite(p, a, compression="zlib", photometric="minisblack"))


def _atomic(path, writer):
    tmp = path + ".tmp.tif"
    writer(tmp)
    os.replace(tmp, path)


def read(path):
    with tifffile.TiffFile(path) as tf:
        page = tf.pages[0]
        if int(page.predictor) != 3:
            return page.asarray()
        return _read_fp_predictor(tf, page)


def _read_fp_predictor(tf, page):
    if int(page.compression) not in (8, 32946, 1):
        raise ValueError(f"unsupported compression {page.compression} with the floating-point predictor")
    bps = page.bitspersample // 8
    h, w = page.imagelength, page.imagewidth
    rows_per = page.rowsperstrip if page.is_tiled is False else None
    if page.is_tiled:
        raise ValueError("tiled float TIFF with the floating-point predictor is not supported")
    out = np.empty((h, w), dtype=np.float32 if bps == 4 else np.float64)
    fh = tf.filehandle
    row = 0
    for off, cnt in zip(page.dataoffsets, page.databytecounts):
        fh.seek(off)
        data = fh.read(cnt)
        if int(page.compression) != 1:
            data = zlib.decompress(data)
        buf = np.frombuffer(data, np.uint8)
        n = min(rows_per, h - row)
        buf = buf[: n * w * bps].reshape(n, w * bps)
        buf = np.cumsum(buf, axis=1, dtype=np.uint64).astype(np.uint8)  # undo byte differencing (mod 256)
        planes = buf.reshape(n, bps, w).transpose(0, 2, 1).copy()  # MSB plane first -> big-endian bytes
        out[row : row + n] = planes.view(">f%d" % bps).reshape(n, w)
        row += n
    return out
