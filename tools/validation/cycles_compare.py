#!/usr/bin/env python3
"""compare CYCLES.exr PRT.exr (PRT.exr the same size or a whole multiple: averaged down) [--tol T] [--min-pixels N] [--name S] [--objects A,B] | sheet OUT.png [--exposure STOPS] [--scale N] [--crop X0,Y0,X1,Y1] ROW... (ROW = a.exr,b.exr,...) | lobes OUT.exr [--degree N]"""
import json, math, struct, sys, zlib

def read_exr(path):
    """Channels of an uncompressed scanline OpenEXR file: {name: [row lists]}, width, height."""
    data = open(path, "rb").read()
    if data[:4] != b"\x76\x2f\x31\x01":
        sys.exit(f"{path}: not an OpenEXR file")
    if struct.unpack_from("<I", data, 4)[0] & 0x1a00:  # bits 9, 11, 12 (bit 10, long names, is fine)
        sys.exit(f"{path}: tiled, deep or multi-part OpenEXR is not read here")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos); name = data[pos:end].decode(); pos = end + 1
        end = data.index(b"\0", pos); kind = data[pos:end].decode(); pos = end + 1
        size = struct.unpack_from("<i", data, pos)[0]; pos += 4
        attrs[name] = (kind, data[pos:pos + size]); pos += size
    pos += 1
    chans, raw = [], attrs["channels"][1]
    p = 0
    while raw[p] != 0:
        end = raw.index(b"\0", p); name = raw[p:end].decode(); p = end + 1
        ptype = struct.unpack_from("<i", raw, p)[0]; p += 16
        chans.append((name, ptype))
    if attrs["compression"][1][0] != 0:
        sys.exit(f"{path}: compressed EXR; write it uncompressed (prt render --exr-compression none)")
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    out = {name: [None] * h for name, _ in chans}
    fmt = {0: "I", 1: "e", 2: "f"}
    pos += 8 * h  # line offset table: blocks follow in file order
    for _ in range(h):
        y, size = struct.unpack_from("<ii", data, pos); pos += 8
        q = pos
        for name, ptype in chans:
            n = struct.calcsize("<" + fmt[ptype])
            out[name][y - y0] = list(struct.unpack_from(f"<{w}{fmt[ptype]}", data, q)); q += n * w
        pos += size
    return out, w, h

def channel(chans, suffix, path):
    names = [n for n in chans if n == suffix or n.endswith("." + suffix)]
    if not names:
        sys.exit(f"{path}: no channel {suffix} (has {', '.join(sorted(chans))})")
    return chans[names[0]]

def average_down(channels, w, h, n):
    """Channels of a (n w) x (n h) image averaged down n x n pixels into one (a box filter)."""
    return [[[sum(ch[n * y + j][n * x + i] for j in range(n) for i in range(n)) / (n * n) for x in range(w)]
             for y in range(h)] for ch in channels]

def rgb(path):
    chans, w, h = read_exr(path)
    return [channel(chans, c, path) for c in "RGB"], w, h

def face_labels(chans, w, h, index_names, path, curved=False):
    """Per pixel 'Object+Y' (normal axis in glTF axes) or None where the pixel is mixed. Faces
    whose normal is more than about 25 degrees off every axis are dropped, unless `curved`
    (a real level's terrain, a hull): then every unmixed pixel is labelled by its dominant axis."""
    idx = channel(chans, "IndexOB.X", path)
    n = [channel(chans, "Normal." + c, path) for c in "XYZ"]
    labels = [[None] * w for _ in range(h)]
    for y in range(h):
        for x in range(w):
            bx, by, bz = n[0][y][x], n[1][y][x], n[2][y][x]
            g = (bx, bz, -by)  # Blender (x, y, z) -> glTF (x, z, -y)
            length = math.sqrt(bx * bx + by * by + bz * bz)
            k = max(range(3), key=lambda i: abs(g[i]))
            obj = index_names.get(round(idx[y][x]))
            axis_ok = curved or abs(g[k]) > 0.9 * length
            if obj and length > 0.97 and axis_ok and abs(idx[y][x] - round(idx[y][x])) < 1e-3:
                labels[y][x] = f"{obj}{'+' if g[k] > 0 else '-'}{'XYZ'[k]}"
    return labels

def erode(labels, w, h, r):
    keep = [[None] * w for _ in range(h)]
    for y in range(r, h - r):
        for x in range(r, w - r):
            lab = labels[y][x]
            if lab and all(labels[y + j][x + i] == lab for j in range(-r, r + 1) for i in range(-r, r + 1)):
                keep[y][x] = lab
    return keep

def drop_creases(labels, chans, w, h, r, path, cos_max=0.9):
    """Labels kept only where every normal within r pixels is within acos(cos_max) (26 degrees)
    of the pixel's own: with `curved` labels, the creases between faces of one axis."""
    n = [channel(chans, "Normal." + c, path) for c in "XYZ"]
    unit = lambda y, x: [n[k][y][x] for k in range(3)]
    keep = [row[:] for row in labels]
    for y in range(h):
        for x in range(w):
            if not labels[y][x]:
                continue
            a = unit(y, x)
            for j in range(max(0, y - r), min(h, y + r + 1)):
                if any(sum(u * v for u, v in zip(a, unit(j, i))) < cos_max for i in range(max(0, x - r), min(w, x + r + 1))):
                    keep[y][x] = None
                    break
    return keep

def quarter_stats(yc, yp):
    """Cycles' darkest and brightest quarter of the pixels: the relative RMS of the difference
    within each (over that quarter's Cycles mean), the median of prt / Cycles, and the ratio of
    the quarter's means."""
    order = sorted(range(len(yc)), key=lambda i: yc[i])
    q = max(1, len(order) // 4)
    out = {}
    for name, idx in (("dark", order[:q]), ("bright", order[-q:])):
        c = [yc[i] for i in idx]
        p = [yp[i] for i in idx]
        ratios = sorted(b / a for a, b in zip(c, p) if a > 0)
        out[name] = {"pixels": q, "rms": math.sqrt(sum((b - a) ** 2 for a, b in zip(c, p)) / q) / (sum(c) / q),
                     "median_ratio": ratios[len(ratios) // 2] if ratios else float("nan"),
                     "mean_ratio": sum(p) / sum(c), "cycles_max": max(c)}
    return out

def diff_png(out, every, yc, yp, w, h, scale=2):
    """Luminance ratio prt / Cycles per compared pixel, false colour: grey = equal, red = prt
    brighter, blue = prt darker (full colour at a factor 2, log scale); dark grey = not compared."""
    img = [[(40, 40, 40)] * w for _ in range(h)]
    for (y, x), a, b in zip(every, yc, yp):
        t = max(-1.0, min(1.0, math.log2(max(b, 1e-9) / max(a, 1e-9))))
        g = int(200 * (1 - abs(t)))
        img[y][x] = (200, g, g) if t > 0 else (g, g, 200)
    rows = []
    for y in range(h * scale):
        rows.append(b"\0" + b"".join(bytes(img[y // scale][x // scale]) for x in range(w * scale)))
    def chunk(t, d): return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w * scale, h * scale, 8, 2, 0, 0, 0)) \
        + chunk(b"IDAT", zlib.compress(b"".join(rows), 9)) + chunk(b"IEND", b"")
    open(out + ".tmp", "wb").write(png)
    import os; os.replace(out + ".tmp", out)

def stats(pixels, c, p, floor):
    """Means of both images over the pixels, relative differences, noise bound of the difference.
    Differences are relative to max(Cycles' mean, floor): a region in full shadow (both ~0) is
    judged against the floor, not against its own rounding noise."""
    n = len(pixels)
    mc = [sum(c[k][y][x] for y, x in pixels) / n for k in range(3)]
    mp = [sum(p[k][y][x] for y, x in pixels) / n for k in range(3)]
    ref = [max(m, floor) for m in mc]
    rel = [(mp[k] - mc[k]) / ref[k] for k in range(3)]
    top = max(mc)
    worst = max((k for k in range(3) if mc[k] >= 0.1 * top), key=lambda k: abs(rel[k]))
    d = [p[worst][y][x] - c[worst][y][x] for y, x in pixels]
    md = sum(d) / n
    se = math.sqrt(sum((v - md) ** 2 for v in d) / max(n - 1, 1) / n) / ref[worst]
    return {"pixels": n, "cycles": mc, "prt": mp, "rel": rel, "worst": rel[worst], "worst_channel": "RGB"[worst],
            "se": se}

def compare(args):
    cyc_path, prt_path = args[0], args[1]
    tol, min_px, name, objects = 0.03, 60, prt_path, []
    second, curved, summary, diff = None, False, None, None
    i = 2
    while i < len(args):
        if args[i] == "--tol": tol = float(args[i + 1]); i += 2
        elif args[i] == "--second": second = args[i + 1]; i += 2  # Cycles with another seed: averaged, and its noise
        elif args[i] == "--curved": curved = True; i += 1  # faces at any angle; creases dropped by the normals
        elif args[i] == "--summary": summary = args[i + 1]; i += 2  # the frame's numbers as JSON
        elif args[i] == "--diff": diff = args[i + 1]; i += 2  # false-colour PNG of prt / Cycles
        elif args[i] == "--objects": objects = args[i + 1].split(","); i += 2  # also the RMS over these objects' faces
        elif args[i] == "--min-pixels": min_px = int(args[i + 1]); i += 2
        elif args[i] == "--name": name = args[i + 1]; i += 2
        else: sys.exit(f"compare: unknown argument {args[i]}")
    meta = json.load(open(cyc_path + ".json"))
    chans, w, h = read_exr(cyc_path)
    c = [channel(chans, "Combined." + k, cyc_path) for k in "RGB"]
    c2 = None
    if second:
        chans2, w2, h2 = read_exr(second)
        if (w2, h2) != (w, h):
            sys.exit(f"{second}: {w2}x{h2}, but {cyc_path} is {w}x{h}")
        c2 = [channel(chans2, "Combined." + k, second) for k in "RGB"]
        c1 = c
        c = [[[(u + v) / 2 for u, v in zip(r1, r2)] for r1, r2 in zip(a, b)] for a, b in zip(c1, c2)]
    p, pw, ph = rgb(prt_path)
    if (pw, ph) != (w, h):
        # A supersampled prt frame (an integer multiple of Cycles' size) is averaged down, N x N
        # pixels into one: the mean radiance over each pixel's square, as Cycles' box filter.
        n = pw // w
        if n < 2 or (pw, ph) != (n * w, n * h):
            sys.exit(f"{prt_path}: {pw}x{ph}, but {cyc_path} is {w}x{h} (nor a whole multiple of it)")
        p = average_down(p, w, h, n)
        print(f"   (prt's {pw}x{ph} frame averaged down {n}x{n} to {w}x{h})")
    index_names = {v: k for k, v in meta["object_index"].items()}
    labels = erode(face_labels(chans, w, h, index_names, cyc_path, curved), w, h, 2)
    if curved:
        labels = drop_creases(labels, chans, w, h, 2, cyc_path)
    regions = {}
    for y in range(h):
        for x in range(w):
            if labels[y][x]:
                regions.setdefault(labels[y][x], []).append((y, x))
                regions.setdefault(f"tile {4 * (3 * y // h) + 4 * x // w:2d} (row {3 * y // h}, col {4 * x // w})", []).append((y, x))
                regions.setdefault("all", []).append((y, x))
    every = regions["all"]
    floor = 0.01 * max(sum(c[k][y][x] for y, x in every) / len(every) for k in range(3))
    print(f"== {name}")
    print(f"   {'region':28s} {'px':>5s} {'Cycles R,G,B':>24s} {'prt R,G,B':>24s} {'rel. diff R,G,B':>24s} {'worst':>7s} {'noise':>6s}")
    worst, failed = 0.0, False
    for key in sorted(regions, key=lambda k: (k == "all", k.startswith("tile"), k)):
        px = regions[key]
        if len(px) < min_px and key != "all":
            continue
        s = stats(px, c, p, floor)
        # A region fails beyond the tolerance plus two standard errors of its noise.
        excess = abs(s["worst"]) - tol - 2 * s["se"]
        flag = "  > tol + 2 noise" if excess > 0 else ""
        worst = max(worst, abs(s["worst"]))
        failed = failed or excess > 0
        fmt3 = lambda v, f: ",".join(f % x for x in v)
        print(f"   {key:28s} {s['pixels']:5d} {fmt3(s['cycles'], '%7.4f'):>24s} {fmt3(s['prt'], '%7.4f'):>24s} "
              f"{fmt3([100 * r for r in s['rel']], '%+6.1f%%'):>24s} {100 * s['worst']:+6.1f}% {100 * s['se']:5.1f}%{flag}")
    # Luminance of the region means: RMS of the relative differences over faces and over tiles.
    lum = lambda m: 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2]
    faces = [k for k in regions if k != "all" and not k.startswith("tile")]
    mine = [k for k in faces if any(k.startswith(o) and k[len(o)] in "+-" for o in objects)]
    for kind, keys in (("faces", faces), ("tiles", [k for k in regions if k.startswith("tile")]),
                       (f"the faces of {'+'.join(objects)}", mine if objects else [])):
        rel = []
        for key in keys:
            if len(regions[key]) >= min_px:
                s = stats(regions[key], c, p, floor)
                rel.append((lum(s["prt"]) - lum(s["cycles"])) / max(lum(s["cycles"]), floor))
        if rel:
            print(f"   RMS over {kind}: {100 * math.sqrt(sum(r * r for r in rel) / len(rel)):.1f}% ({len(rel)} regions, "
                  f"relative difference of the luminance of each region's mean; largest {100 * max(map(abs, rel)):.1f}%)")
    subsets = [("", every)]
    if objects:
        subsets.append((f" of {'+'.join(objects)}", [px for k in mine for px in regions[k]]))
    for label, pixels in subsets:
        if not pixels:
            continue
        yc = [lum([c[k][y][x] for k in range(3)]) for y, x in pixels]
        yp = [lum([p[k][y][x] for k in range(3)]) for y, x in pixels]
        mean_c = sum(yc) / len(yc)
        print(f"   pixel relative RMS{label}: {100 * math.sqrt(sum((a - b) ** 2 for a, b in zip(yp, yc)) / len(yc)) / mean_c:.1f}% "
              f"(luminance, {len(yc)} pixels away from edges, over the mean; holds Cycles' per-pixel noise too; "
              f"mean prt/Cycles {sum(yp) / sum(yc):.3f})")
    yc = [lum([c[k][y][x] for k in range(3)]) for y, x in every]
    yp = [lum([p[k][y][x] for k in range(3)]) for y, x in every]
    res = {"name": name, "pixels": len(every), "frame_rms": math.sqrt(sum((a - b) ** 2 for a, b in zip(yp, yc)) / len(yc))
           / (sum(yc) / len(yc)), "mean_ratio": sum(yp) / sum(yc)}
    res.update(quarter_stats(yc, yp))
    for q in ("dark", "bright"):
        s = res[q]
        print(f"   Cycles' {'darkest' if q == 'dark' else 'brightest'} quarter ({s['pixels']} pixels, Cycles luminance "
              f"{'up to' if q == 'dark' else 'from'} {s['cycles_max'] if q == 'dark' else min(sorted(yc)[-s['pixels']:]):.4f}): "
              f"relative RMS {100 * s['rms']:.1f}%, median prt/Cycles {s['median_ratio']:.3f}, means {s['mean_ratio']:.3f}")
    if c2:
        # Noise of the two seeds' mean: half their difference per pixel (the same pixels, luminance).
        y1 = [lum([c1[k][y][x] for k in range(3)]) for y, x in every]
        y2 = [lum([c2[k][y][x] for k in range(3)]) for y, x in every]
        half = [(a - b) / 2 for a, b in zip(y1, y2)]
        res["cycles_noise"] = math.sqrt(sum(d * d for d in half) / len(half)) / (sum(yc) / len(yc))
        dark = sorted(range(len(yc)), key=lambda i: yc[i])[:res["dark"]["pixels"]]
        res["cycles_noise_dark"] = math.sqrt(sum(half[i] ** 2 for i in dark) / len(dark)) / (sum(yc[i] for i in dark) / len(dark))
        print(f"   Cycles' noise (the mean of two seeds, half their difference): pixel relative RMS "
              f"{100 * res['cycles_noise']:.1f}%, in the darkest quarter {100 * res['cycles_noise_dark']:.1f}%")
    if summary:
        json.dump(res, open(summary, "w"), indent=1)
    if diff:
        diff_png(diff, every, yc, yp, w, h)
    verdict = "FAIL" if failed else "PASS"
    print(f"   {verdict}: largest regional difference {100 * worst:.1f}% (a region fails beyond {100 * tol:.1f}% "
          f"+ 2 noise; regions of >= {min_px} pixels; noise = standard error of the region's mean difference)")
    return 0 if verdict == "PASS" else 3

def srgb8(v):
    v = min(max(v, 0.0), 1.0)
    v = 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(round(255 * v))

def sheet(args):
    """Rows of images side by side, 2x nearest upscaling, exposure, clamp + sRGB (Blender's
    Standard view transform)."""
    out, rows, scale, gap, gain, crop = args[0], [], 2, 4, 1.0, None
    while args[1].startswith("--"):
        if args[1] == "--exposure": gain = 2.0 ** float(args[2])
        elif args[1] == "--scale": scale = int(args[2])
        elif args[1] == "--crop": crop = [int(v) for v in args[2].split(",")]  # X0,Y0,X1,Y1 (pixels, end excluded)
        else: sys.exit(f"sheet: unknown option {args[1]}")
        args = args[:1] + args[3:]
    for row in args[1:]:
        imgs = []
        for path in row.split(","):
            chans, w, h = read_exr(path)
            imgs.append(([channel(chans, k if k in chans else "Combined." + k, path) for k in "RGB"], w, h))
        # Images a whole multiple of the row's smallest (supersampled prt frames) are averaged down to it.
        hmin = min(ih for _, _, ih in imgs)
        for n, (img, w, ih) in enumerate(imgs):
            f = ih // hmin
            if f > 1 and ih == f * hmin and w % f == 0:
                imgs[n] = (average_down(img, w // f, hmin, f), w // f, hmin)
        if crop:
            x0, y0, x1, y1 = crop
            imgs = [([[r[x0:x1] for r in c[y0:y1]] for c in img], x1 - x0, y1 - y0) for img, _, _ in imgs]
        rows.append(imgs)
    width = max(sum(scale * w + gap for _, w, _ in r) - gap for r in rows)
    lines = []
    for r in rows:
        h = max(ih for _, _, ih in r)
        for y in range(h * scale):
            line = bytearray()
            for n, (img, w, ih) in enumerate(r):
                if n: line += b"\xff\xff\xff" * gap
                yy = min(y // scale, ih - 1)
                for x in range(w * scale):
                    line += bytes(srgb8(gain * img[k][yy][x // scale]) for k in range(3))
            line += b"\xff\xff\xff" * (width - len(line) // 3)
            lines.append(bytes(line))
        lines.append(b"\xff\xff\xff" * width * 1)
        lines.append(b"\xff\xff\xff" * width * 1)
    lines = lines[:-2]
    raw = b"".join(b"\0" + l for l in lines)
    def chunk(t, d): return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, len(lines), 8, 2, 0, 0, 0)) \
        + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    open(out + ".tmp", "wb").write(png)
    import os; os.replace(out + ".tmp", out)
    print(f"wrote {out} ({width}x{len(lines)})")
    return 0

LOBES = [  # (colour, axis): one lobe 0.1 + 2 ((1 + a.d) / 2)^4 per channel, 45 degrees above the horizon
    (0, (math.sqrt(0.5), math.sqrt(0.5), 0.0)),    # red towards +X
    (1, (0.0, math.sqrt(0.5), math.sqrt(0.5))),    # green towards +Z
    (2, (-math.sqrt(0.5), math.sqrt(0.5), 0.0)),   # blue towards -X
]

def lobes(args):
    """A band-limited, positive, coloured sky: each channel a polynomial of degree 4 (or
    `--degree N`) in the direction d, so exactly bands 0..N (N + 1 bands: `--degree 2` is what
    prt's default 3 bands hold exactly); written as an uncompressed float EXR with pixel centres
    placed as docs/lights.md says (glTF axes): theta = pi v, phi = 2 pi (u - 0.5),
    d = (sin theta cos phi, cos theta, sin theta sin phi)."""
    out, w, h, degree = args[0], 256, 128, 4
    if args[1:3] and args[1] == "--degree":
        degree = int(args[2])
    rows = []
    for j in range(h):
        theta = math.pi * (j + 0.5) / h
        row = [[0.0] * w for _ in range(3)]
        for i in range(w):
            phi = 2 * math.pi * ((i + 0.5) / w - 0.5)
            d = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            for k, a in LOBES:
                row[k][i] = 0.1 + 2.0 * ((1 + sum(x * y for x, y in zip(a, d))) / 2) ** degree
        rows.append(row)
    def attr(name, kind, value): return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value
    chl = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    header = b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + attr("channels", "chlist", chl) \
        + attr("compression", "compression", b"\0") + attr("dataWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1)) \
        + attr("displayWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1)) + attr("lineOrder", "lineOrder", b"\0") \
        + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)) \
        + attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)) \
        + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0"
    block = 8 + 12 * w
    table = b"".join(struct.pack("<Q", len(header) + 8 * h + j * block) for j in range(h))
    body = b"".join(struct.pack("<ii", j, 12 * w) + b"".join(struct.pack(f"<{w}f", *rows[j][k]) for k in (2, 1, 0))
                    for j in range(h))
    open(out + ".tmp", "wb").write(header + table + body)
    import os; os.replace(out + ".tmp", out)
    return 0

if __name__ == "__main__":
    mode = sys.argv[1]
    sys.exit({"compare": compare, "sheet": sheet, "lobes": lobes}[mode](sys.argv[2:]))
