"""make_textures.py - writes the small test textures of scenes/assets/ (run from that folder).

uvgrid.png   16 x 8 sRGB RGBA, every texel different: R rises to the right, G downward, B a
             checker, alpha a ramp from 1 (left) to 0.29 (right): a half-texel shift, a flipped v
             or a swapped channel shows in every twin.
specramp.png 8 x 8 grey, a ramp 0 .. 1 (sRGB-coded) to the right: a specular colour map.
Written with zlib only (no imaging library), so the bytes are reproducible.
"""

import struct
import zlib


def png(path, w, h, px, alpha=False):
    ct = 6 if alpha else 2
    raw = b"".join(b"\x00" + bytes(sum((list(px(x, y)) for x in range(w)), [])) for y in range(h))

    def chunk(t, d):
        c = struct.pack(">I", len(d)) + t + d
        return c + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    data = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, ct, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )
    with open(path, "wb") as f:
        f.write(data)


def uvgrid(x, y):
    return (int(30 + 14 * x), int(40 + 26 * y), 230 if (x + y) % 2 else 60, int(255 - 12 * x))


if __name__ == "__main__":
    png("uvgrid.png", 16, 8, uvgrid, alpha=True)
    png("specramp.png", 8, 8, lambda x, y: (int(255 * x / 7),) * 3)
