#!/usr/bin/env python3
"""A second reader of Landform's height maps, in plain Python (standard library only): decodes
heightmap.png (16-bit grayscale, z_min/z_max in tEXt chunks), heightmap.r16 (raw little-endian
u16, sizes and range given on the command line, as the job's result states them) and
heightfield.npy (f32), and checks that both maps agree with the float heights to within one
16-bit step. Prints a JSON summary; exits 1 on any disagreement.

Usage: read_maps.py DIR WIDTH HEIGHT Z_MIN Z_MAX
"""
import json
import struct
import sys
import zlib


def png_gray16(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, text = 8, b"", {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, color = struct.unpack(">IIBB", body[:10])
            assert (depth, color) == (16, 0), "16-bit grayscale expected"
        elif kind == b"IDAT":
            idat += body
        elif kind == b"tEXt":
            key, value = body.split(b"\0", 1)
            text[key.decode("latin-1")] = value.decode("latin-1")
    raw, bpp, stride = zlib.decompress(idat), 2, width * 2
    rows, prev, i = [], bytearray(stride), 0
    for _ in range(height):
        kind, line = raw[i], bytearray(raw[i + 1 : i + 1 + stride])
        i += 1 + stride
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b, c = prev[x], (prev[x - bpp] if x >= bpp else 0)
            if kind == 1:
                line[x] = (line[x] + a) & 255
            elif kind == 2:
                line[x] = (line[x] + b) & 255
            elif kind == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    samples = [v for row in rows for v in struct.unpack(">%dH" % width, bytes(row))]
    return width, height, samples, text


def npy_f32(path):
    data = open(path, "rb").read()
    assert data[:6] == b"\x93NUMPY", "not a .npy"
    (header_len,) = struct.unpack("<H", data[8:10])
    header = data[10 : 10 + header_len].decode("latin-1")
    assert "'descr': '<f4'" in header, header
    body = data[10 + header_len :]
    return list(struct.unpack("<%df" % (len(body) // 4), body))


def main():
    folder, width, height = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    z_min, z_max = float(sys.argv[4]), float(sys.argv[5])
    step = (z_max - z_min) / 65535.0
    heights = npy_f32(folder + "/heightfield.npy")
    raw = open(folder + "/heightmap.r16", "rb").read()
    assert len(raw) == 2 * width * height == 2 * len(heights), (len(raw), width, height, len(heights))
    r16 = struct.unpack("<%dH" % (width * height), raw)
    png_w, png_h, png, text = png_gray16(folder + "/heightmap.png")
    assert (png_w, png_h) == (width, height), (png_w, png_h)
    assert abs(float(text["z_min"]) - z_min) < 1e-3 and abs(float(text["z_max"]) - z_max) < 1e-3, text
    worst = {"r16": 0.0, "png": 0.0}
    for name, samples in (("r16", r16), ("png", png)):
        for q, h in zip(samples, heights):
            worst[name] = max(worst[name], abs(z_min + q * step - h))
    ok = all(w <= step * 1.001 + 1e-6 for w in worst.values()) and list(r16) == list(png)
    print(json.dumps({"ok": ok, "step_m": step, "worst_m": worst, "samples": len(heights)}))
    sys.exit(0 if ok else 1)


main()
