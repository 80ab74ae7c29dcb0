#!/usr/bin/env python3
"""Writes the bundled environment maps in scenes/env/ (Radiance .hdr, equirectangular).

    python3 scenes/make_env.py [HDRI_DIR]   # default: the first of ../shared/hdri and
                                            # ../../shared/hdri (from the repo root) that exists

- royal_esplanade_128.hdr: Poly Haven's royal_esplanade_1k.hdr (CC0, via the three.js
  examples) box-filtered from 1024×512 to 128×64 in linear float: each output pixel is the
  solid-angle-weighted mean of an 8×8 block, which keeps the map's power.
- white_sky_64.hdr: 64×32, radiance exactly 1.0 everywhere (RGBE bytes 128 128 128 129), for
  the units check: a white, unoccluded, upward surface must come out at exactly 1.

Standard library only and deterministic. Decodes RGBE like stb_image and Radiance's rgbe.c:
value = mantissa · 2^(exponent − 136), 0 when the exponent byte is 0 (no +0.5 offset).
"""

import math
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


class HdrError(Exception):
    pass


def read_hdr(path):
    """Returns (width, height, pixels) with pixels a flat list of [r, g, b] floats, row 0 at
    the top. Reads flat and new-style run-length encoded scanlines of '-Y H +X W' files."""
    with open(path, "rb") as f:
        data = f.read()
    pos = 0

    def line():
        nonlocal pos
        end = data.index(b"\n", pos)
        text = data[pos:end].decode("ascii", "replace")
        pos = end + 1
        return text

    magic = line()
    if not magic.startswith("#?"):
        raise HdrError("%s: not a Radiance file (magic %r)" % (path, magic))
    while True:
        text = line()
        if text == "":
            break
        if text.startswith("FORMAT=") and text != "FORMAT=32-bit_rle_rgbe":
            raise HdrError("%s: unsupported %s" % (path, text))
    res = line().split()
    if len(res) != 4 or res[0] != "-Y" or res[2] != "+X":
        raise HdrError("%s: unsupported orientation %r" % (path, " ".join(res)))
    height, width = int(res[1]), int(res[3])

    pixels = []
    scan = bytearray(4 * width)
    for y in range(height):
        if width >= 8 and width < 32768 and data[pos] == 2 and data[pos + 1] == 2 \
                and not data[pos + 2] & 0x80:
            if (data[pos + 2] << 8 | data[pos + 3]) != width:
                raise HdrError("%s: scanline %d: width mismatch" % (path, y))
            pos += 4
            for c in range(4):  # channels stored one after the other, each run-length coded
                x = 0
                while x < width:
                    count = data[pos]
                    pos += 1
                    if count > 128:
                        count -= 128
                        if x + count > width:
                            raise HdrError("%s: scanline %d: run too long" % (path, y))
                        value = data[pos]
                        pos += 1
                        for i in range(x, x + count):
                            scan[4 * i + c] = value
                    else:
                        if count == 0 or x + count > width:
                            raise HdrError("%s: scanline %d: bad literal count" % (path, y))
                        for i in range(count):
                            scan[4 * (x + i) + c] = data[pos + i]
                        pos += count
                    x += count
        else:
            if pos + 4 * width > len(data):
                raise HdrError("%s: truncated at scanline %d" % (path, y))
            scan[:] = data[pos:pos + 4 * width]
            pos += 4 * width
        for x in range(width):
            r, g, b, e = scan[4 * x:4 * x + 4]
            if e == 0:
                pixels.append([0.0, 0.0, 0.0])
            else:
                f = math.ldexp(1.0, e - 136)
                pixels.append([r * f, g * f, b * f])
    return width, height, pixels


def to_rgbe(rgb):
    """Float → RGBE: the largest channel gets a mantissa in [128, 256). Mantissas are rounded
    to nearest (Ward's rgbe.c truncates, which with the decoders' m · 2^(e−136) loses half a
    step, ~0.4% of the power, on average)."""
    v = max(rgb)
    if v < 1e-32:
        return (0, 0, 0, 0)
    m, e = math.frexp(v)
    scale = m * 256.0 / v
    if int(v * scale + 0.5) > 255:  # the largest channel rounds up to 256: next exponent
        scale, e = scale / 2, e + 1
    return tuple(int(c * scale + 0.5) for c in rgb) + (e + 128,)


def rle_channel(values):
    """New-style RLE of one channel of one scanline: runs of ≥ 4 equal bytes as (128 + n, b),
    everything else as literal blocks (n ≤ 128, then n bytes)."""
    out = bytearray()
    i, n = 0, len(values)
    while i < n:
        # Find the next run of at least 4 equal bytes starting at or after i.
        run_start, run_len = n, 0
        j = i
        while j < n:
            k = j
            while k < n and k - j < 127 and values[k] == values[j]:
                k += 1
            if k - j >= 4:
                run_start, run_len = j, k - j
                break
            j += 1
        while i < run_start:  # literals before the run
            count = min(128, run_start - i)
            out.append(count)
            out += bytes(values[i:i + count])
            i += count
        if run_len:
            out += bytes((128 + run_len, values[run_start]))
            i = run_start + run_len
    return out


def write_hdr(path, width, height, pixels):
    out = bytearray(b"#?RADIANCE\n# written by prt scenes/make_env.py\n"
                    b"FORMAT=32-bit_rle_rgbe\n\n")
    out += b"-Y %d +X %d\n" % (height, width)
    for y in range(height):
        rgbe = [to_rgbe(pixels[y * width + x]) for x in range(width)]
        out += bytes((2, 2, width >> 8, width & 0xFF))
        for c in range(4):
            out += rle_channel([p[c] for p in rgbe])
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(out)
    os.replace(tmp, path)


def row_solid_angle(y, height):
    """Solid angle of row y of an equirectangular map, per unit of 2π/width."""
    return math.cos(math.pi * y / height) - math.cos(math.pi * (y + 1) / height)


def box_filter(width, height, pixels, factor):
    """Each output pixel is the mean of a factor × factor block, each source pixel weighted by
    its exact solid angle (∝ cos θ₀ − cos θ₁ of its row edges, as prt's SH projection weights
    pixels): the output's power equals the source's under that projection (an unweighted mean
    moves a small bright sun's power by a few percent)."""
    w, h = width // factor, height // factor
    assert w * factor == width and h * factor == height
    weight = [row_solid_angle(y, height) for y in range(height)]
    out = []
    for y in range(h):
        rows = range(y * factor, (y + 1) * factor)
        inv = 1.0 / (factor * sum(weight[r] for r in rows))
        for x in range(w):
            acc = [0.0, 0.0, 0.0]
            for r in rows:
                base, wr = r * width + x * factor, weight[r]
                for dx in range(factor):
                    p = pixels[base + dx]
                    acc[0] += wr * p[0]
                    acc[1] += wr * p[1]
                    acc[2] += wr * p[2]
            out.append([a * inv for a in acc])
    return w, h, out


def rgbe_rounded(pixels):
    """What the pixels read back as after RGBE encoding."""
    out = []
    for p in pixels:
        r, g, b, e = to_rgbe(p)
        f = math.ldexp(1.0, e - 136) if e else 0.0
        out.append([r * f, g * f, b * f])
    return out


def solid_angle_mean(width, height, pixels):
    """Mean radiance over the sphere, each pixel weighted by its solid angle."""
    acc, total = [0.0, 0.0, 0.0], 0.0
    for y in range(height):
        w = row_solid_angle(y, height)
        for x in range(width):
            p = pixels[y * width + x]
            for c in range(3):
                acc[c] += w * p[c]
            total += w
    return [a / total for a in acc]


def main():
    if len(sys.argv) > 1:
        hdri = sys.argv[1]
    else:
        candidates = [os.path.join(HERE, "..", up, "shared", "hdri") for up in ("..", "../..")]
        hdri = next((c for c in candidates if os.path.isdir(c)), candidates[0])
    env = os.path.join(HERE, "env")
    os.makedirs(env, exist_ok=True)

    src = os.path.join(hdri, "royal_esplanade_1k.hdr")
    w, h, px = read_hdr(src)
    sw, sh, small = box_filter(w, h, px, w // 128)
    assert (sw, sh) == (128, 64)
    dst = os.path.join(env, "royal_esplanade_128.hdr")
    write_hdr(dst, sw, sh, small)
    back = read_hdr(dst)[2]
    assert back == rgbe_rounded(small), "RGBE round trip differs"
    print("%s: %dx%d -> %dx%d, mean radiance %s (source %s), peak %.1f"
          % (os.path.relpath(dst), w, h, sw, sh,
             " ".join("%.4f" % v for v in solid_angle_mean(sw, sh, back)),
             " ".join("%.4f" % v for v in solid_angle_mean(w, h, px)),
             max(max(p) for p in back)))

    dst = os.path.join(env, "white_sky_64.hdr")
    write_hdr(dst, 64, 32, [[1.0, 1.0, 1.0]] * (64 * 32))
    back = read_hdr(dst)[2]
    assert all(p == [1.0, 1.0, 1.0] for p in back) and len(back) == 64 * 32
    print("%s: 64x32, radiance 1.0 exactly" % os.path.relpath(dst))


if __name__ == "__main__":
    main()
