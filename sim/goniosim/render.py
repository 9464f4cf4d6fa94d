"""Render one capture from the true geometry and write it as Radiance .hdr or OpenEXR."""

from __future__ import annotations

import functools
import math
import os

import numpy as np

from .material import Material, Realism, specular

HOLDER_ALBEDO = (0.10, 0.10, 0.11)


@functools.lru_cache(maxsize=8)
def _pixel_grid(h: int, w: int, holder_px: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sample's mask inside the holder border, and the pixel centres u, v (each in its own
    axis's units, from the image centre). The same for every capture of a run, so built once;
    the arrays are read-only because they are shared."""
    mask = np.zeros((h, w), dtype=bool)
    mask[holder_px : h - holder_px, holder_px : w - holder_px] = True
    y, x = np.mgrid[0:h, 0:w]
    u = (x + 0.5) / w - 0.5
    v = (y + 0.5) / h - 0.5
    for a in (mask, u, v):
        a.setflags(write=False)
    return mask, u, v


def render(
    albedo: np.ndarray,
    wi: np.ndarray,
    wo: np.ndarray,
    material: Material,
    realism: Realism,
    gain: float,
    holder_px: int,
) -> np.ndarray:
    """Noiseless linear RGB image (H, W, 3), float64.

    A white Lambertian reflector at normal incidence renders as 1.0 (pixel = gain * pi * cos
    theta_i * f_r). The sample occupies the image inside a holder border of `holder_px`.
    """
    h, w, _ = albedo.shape
    ci = max(float(wi[2]), 0.0)
    mask, u, v = _pixel_grid(h, w, holder_px)
    if realism.d is not None and realism.d.bow != 0.0:
        img = gain * bowed(albedo, u, v * (h / w), wi, wo, material, realism.d)
    elif realism.e is not None:
        img = gain * wedged(albedo, wi, wo, material, realism.e)
    else:
        spec = specular(wi, wo, material)
        img = gain * ci * (albedo + math.pi * spec)  # pi * (albedo/pi + spec)
    if realism.e is not None and realism.e.wall > 0.0:
        img = img + gain * bracket_light(u, v * (h / w), wi, realism.e)[..., None] * albedo * np.asarray(realism.e.wall_rgb)
    holder = gain * ci * np.array(HOLDER_ALBEDO)
    if realism.footprint > 0.0:
        # lamp footprint: along the projected light direction
        pi_az = math.atan2(wi[1], wi[0])
        s = u * math.cos(pi_az) + v * math.sin(pi_az)
        ti2 = (1.0 - ci * ci) / max(ci * ci, 1e-6)
        k = np.asarray(realism.footprint_rgb)
        img = img * np.exp(-realism.footprint * min(ti2, 20.0) * (s**2)[..., None] * k)
    if realism.bleed_px > 0.0:
        co = max(float(wo[2]), 1e-6)
        to = math.sqrt(max(1.0 - co * co, 0.0)) / co
        bleed = realism.bleed_px * min(to, 10.0)
        po_az = math.atan2(wo[1], wo[0])
        # distance from the sample's edge across the view azimuth, in pixels
        t = np.abs(u * math.cos(po_az) + v * math.sin(po_az))
        half = 0.5 * (w - 2 * holder_px) / w
        inside_edge = (half - t) * w
        mask = mask & (inside_edge > bleed)
    jaw = realism.d is not None and realism.d.jaw_height > 0.0
    if jaw:
        # the jaw covers the sample beyond its line (a square sample's corner): seen as the holder
        edge = 0.5 - holder_px / w
        mask = mask & (jaw_inside(u, v * (h / w), edge, realism.d) >= 0.0)
    out = np.where(mask[..., None], img, holder)
    if realism.b is not None:
        # realism_b works in image-width units on both axes (u already is)
        out = realism_b(out, u, v * (h / w), wi, wo, realism.b, gain)
    if realism.c is not None:
        out = realism_c(out, w, h, wi, wo, realism.c, gain, ci)
    if jaw:
        out = jaw_shadow(out, mask, w, h, 0.5 - holder_px / w, wi, realism.d)
    return out


# the bowed surface's tilt is evaluated at this many positions across its axis and interpolated
BOW_STEPS = 17


def _to_local(n: np.ndarray, x: np.ndarray) -> np.ndarray:
    """`x` in the frame whose normal is the unit vector `n` (the rotation taking n to +z about
    n × z)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(n, z)
    s = float(np.linalg.norm(axis))
    c = float(n[2])
    if s < 1e-12:
        return x
    k = axis / s
    return x * c + np.cross(k, x) * s + k * float(np.dot(k, x)) * (1.0 - c)


def bowed(albedo: np.ndarray, u: np.ndarray, v: np.ndarray, wi: np.ndarray, wo: np.ndarray, material: Material, d) -> np.ndarray:
    """cos theta_i * (albedo + pi * f_s) of a bowed sample (`RealismD`), each pixel in the frame
    of its own normal; u, v in image-width units from the image centre."""
    a = math.radians(d.bow_axis_deg)
    # across the cylinder's axis, which lies along (cos a, sin a)
    across = np.array([-math.sin(a), math.cos(a), 0.0])
    s = u * across[0] + v * across[1]
    grid = np.linspace(-0.75, 0.75, BOW_STEPS)
    cos_i, lobe = np.zeros(BOW_STEPS), np.zeros(BOW_STEPS)
    for k, sk in enumerate(grid):
        slope = 8.0 * d.bow * sk
        n = np.array([slope * across[0], slope * across[1], 1.0])
        n = n / np.linalg.norm(n)
        li, lo = _to_local(n, wi), _to_local(n, wo)
        cos_i[k] = max(float(li[2]), 0.0)
        lobe[k] = cos_i[k] * math.pi * specular(li, lo, material) if lo[2] > 0.0 else 0.0
    ci_px = np.interp(s, grid, cos_i)
    lobe_px = np.interp(s, grid, lobe)
    return ci_px[..., None] * albedo + lobe_px[..., None]


def wedged(albedo: np.ndarray, wi: np.ndarray, wo: np.ndarray, material: Material, e) -> np.ndarray:
    """cos theta_i * (albedo + pi * f_s) of a sample seated on a wedge (`RealismE`): lit and seen
    in the frame of its tilted normal, with the model's trace of anisotropy."""
    a, t = math.radians(e.wedge_azimuth_deg), math.radians(e.wedge_deg)
    n = np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])
    li, lo = _to_local(n, wi), _to_local(n, wo)
    ci = max(float(li[2]), 0.0)
    lobe = math.pi * specular(li, lo, e.material(material)) if lo[2] > 0.0 else 0.0
    return ci * (albedo + lobe)


def bracket_light(u: np.ndarray, v: np.ndarray, wi: np.ndarray, e) -> np.ndarray:
    """The irradiance the bracket's face (`RealismE`) sends to each point, in units of the lamp's
    at normal incidence; u, v in image widths from the image centre."""
    ci = max(float(wi[2]), 0.0)
    sin_i = math.sqrt(max(1.0 - ci * ci, 0.0))
    if sin_i == 0.0:
        return np.zeros(np.shape(u))
    a = math.radians(e.wall_azimuth_deg)
    facing = max(math.cos(math.atan2(wi[1], wi[0]) - a), 0.0)
    near = 1.0 + e.wall_gradient * 2.0 * (u * math.cos(a) + v * math.sin(a))
    return e.wall * sin_i * facing * near


def jaw_inside(u: np.ndarray, v: np.ndarray, edge: float, d) -> np.ndarray:
    """Each point's distance inside the jaw's line, which stands `edge` image widths from the
    centre towards the jaw (negative under the jaw)."""
    jaw = math.radians(d.jaw_azimuth_deg)
    return edge - (u * math.cos(jaw) + v * math.sin(jaw))


def jaw_shadow(img: np.ndarray, mask: np.ndarray, w: int, h: int, edge: float, wi: np.ndarray, d) -> np.ndarray:
    """The gripper jaw's shadow (`RealismD`) on the sample, whose edges stand `edge` image widths
    from the centre: a band along the jaw's line that narrows to nothing as the light turns away
    from the jaw's side; supersampled like the third model's rim, so that it does."""
    ci = max(float(wi[2]), 1e-6)
    ti = min(math.sqrt(max(1.0 - ci * ci, 0.0)) / ci, 10.0)
    facing = math.cos(math.atan2(wi[1], wi[0]) - math.radians(d.jaw_azimuth_deg))
    width = d.jaw_height * ti * max(facing, 0.0)
    if width <= 0.0:
        return img
    us, vs = _subpixel_grid(h, w)
    t = jaw_inside(us, vs, edge, d)
    # lit beyond the band (points under the jaw are the holder's, in no shadow of its own); the
    # penumbra shrinks with the band, so the shadow fades out with it
    pen = d.jaw_penumbra * min(1.0, width / d.jaw_height)
    lit = np.where(t < 0.0, 1.0, 0.5 * (1.0 + np.tanh((t - width) / max(pen, 1e-9)))).mean(axis=-1)
    keep = np.where(mask, d.jaw_ambient + (1.0 - d.jaw_ambient) * lit, 1.0)
    return img * keep[..., None]


# the rim's supersampling: SUB × SUB points a pixel
SUB = 4


@functools.lru_cache(maxsize=8)
def _subpixel_grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """SUB × SUB sample points per pixel, in image-width units from the image centre, shaped
    (h, w, SUB²); read-only because shared."""
    off = (np.arange(SUB) + 0.5) / SUB
    y, x = np.mgrid[0:h, 0:w]
    ox, oy = np.meshgrid(off, off)
    u = (x[..., None] + ox.ravel()) / w - 0.5
    v = ((y[..., None] + oy.ravel()) / h - 0.5) * (h / w)
    for a in (u, v):
        a.setflags(write=False)
    return u, v


def _outside_rim(u: np.ndarray, v: np.ndarray, c) -> np.ndarray:
    """Signed distance beyond the rim's hexagonal opening (negative inside), image widths."""
    r_in = c.rim_radius * math.cos(math.pi / 6.0)
    d = np.full(u.shape, -np.inf)
    for k in range(6):
        a = math.radians(c.rim_rotation_deg) + k * math.pi / 3.0 + math.pi / 6.0
        d = np.maximum(d, u * math.cos(a) + v * math.sin(a))
    return d - r_in


def _through_rim(u: np.ndarray, v: np.ndarray, w: np.ndarray, c) -> np.ndarray:
    """The share of each point's view along direction `w` (sample frame) that clears the rim:
    the ray crosses the rim's height recess * tan(theta) from the point, towards w's azimuth,
    and clears it inside the opening, under a penumbra that widens with that distance."""
    cw = max(float(w[2]), 1e-6)
    shift = c.recess * min(math.sqrt(max(1.0 - cw * cw, 0.0)) / cw, 10.0)
    az = math.atan2(w[1], w[0])
    d = _outside_rim(u + shift * math.cos(az), v + shift * math.sin(az), c)
    pen = c.penumbra + c.penumbra_growth * shift
    return 0.5 * (1.0 - np.tanh(d / pen))


def realism_c(img: np.ndarray, w: int, h: int, wi: np.ndarray, wo: np.ndarray, c, gain: float, ci: float) -> np.ndarray:
    """The third nuisance model (`RealismC`) applied to a rendered image."""
    us, vs = _subpixel_grid(h, w)
    out = img
    if c.recess > 0.0:
        lit = _through_rim(us, vs, wi, c)
        seen = _through_rim(us, vs, wo, c)
        # per pixel: the sample where seen (lit or in the shadow's ambient), else the rim's wall
        light = (seen * (c.ambient + (1.0 - c.ambient) * lit)).mean(axis=-1)
        wall = (1.0 - seen).mean(axis=-1)
        out = out * light[..., None] + (gain * ci * c.wall_albedo) * wall[..., None]
    u = us.mean(axis=-1)
    v = vs.mean(axis=-1)
    if c.beam_sigma > 0.0:
        n = np.cross(wi, wo)
        norm = float(np.linalg.norm(n))
        if norm > 1e-9:
            n = n / norm
            t = np.cross(n, wi)
            wy = u * t[0] + v * t[1] - c.beam_offset[0]
            wz = u * n[0] + v * n[1] - c.beam_offset[1]
            beam = np.exp(-(wy * wy + wz * wz) / (2.0 * c.beam_sigma**2))
            out = out * beam[..., None]
    if c.lamp_distance > 0.0:
        sin_i = math.sqrt(max(1.0 - ci * ci, 0.0))
        az = math.atan2(wi[1], wi[0])
        near = 1.0 - 2.0 * (u * math.cos(az) + v * math.sin(az)) * sin_i / c.lamp_distance
        out = out * near[..., None]
    if c.response_gamma != 0.0:
        out = np.power(np.clip(out, 0.0, None), 1.0 + c.response_gamma)
    return out


def realism_b(img: np.ndarray, u: np.ndarray, v: np.ndarray, wi: np.ndarray, wo: np.ndarray, b, gain: float) -> np.ndarray:
    """The second nuisance model (`RealismB`) applied to a rendered image; u, v are the pixel
    centres in image-width units from the image centre."""
    ci = max(float(wi[2]), 1e-6)
    co = max(float(wo[2]), 1e-6)
    ti = math.sqrt(max(1.0 - ci * ci, 0.0)) / ci
    to = math.sqrt(max(1.0 - co * co, 0.0)) / co
    pi_az = math.atan2(wi[1], wi[0])
    po_az = math.atan2(wo[1], wo[0])
    # where the lamp's spot centre appears in the image: shifted on the sample towards the lamp,
    # and the sample shifted in the image by the parallax
    h, (dx, dy) = b.mount_height, b.mount_offset
    cx = h * min(ti, 10.0) * math.cos(pi_az) - h * min(to, 10.0) * math.cos(po_az) - dx
    cy = h * min(ti, 10.0) * math.sin(pi_az) - h * min(to, 10.0) * math.sin(po_az) - dy
    spot = np.exp(-((u - cx) ** 2 + (v - cy) ** 2) / (2.0 * b.spot_sigma**2))
    so = 1.0 - co * co
    vig = np.exp(-b.vignette * (u**2 + v**2) * (1.0 + b.vignette_theta * so))
    out = img * (spot * vig)[..., None]
    wagon = math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(wi, wo))))))
    veil = gain * b.stray * math.exp(-wagon / b.stray_scale_deg)
    return out + veil * np.asarray(b.stray_rgb)


def add_noise(img: np.ndarray, rng: np.random.Generator, photons_per_unit: float, read_noise: float) -> np.ndarray:
    """Shot noise (Gaussian approximation of Poisson with `photons_per_unit` at value 1) + read noise."""
    sigma = np.sqrt(np.clip(img, 0.0, None) / photons_per_unit + read_noise * read_noise)
    return img + rng.normal(0.0, 1.0, img.shape) * sigma


def encode_rgbe(img: np.ndarray) -> bytes:
    """Flat (uncompressed) RGBE scanlines, top row first."""
    # NaN and Inf have no RGBE form: NaN and -Inf are stored as 0, +Inf as the largest value
    finite = np.isfinite(img).all()
    rgb = np.maximum(img if finite else np.nan_to_num(img, nan=0.0, posinf=1e38, neginf=0.0), 0.0)
    m = rgb.max(axis=2)
    mant, exp = np.frexp(m)
    scale = np.where(m > 1e-32, mant * 256.0 / np.where(m > 0, m, 1.0), 0.0)
    out = np.zeros(rgb.shape[:2] + (4,), dtype=np.uint8)
    out[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(m > 1e-32, exp + 128, 0).clip(0, 255).astype(np.uint8)
    return out.tobytes()


def hdr_bytes(img: np.ndarray) -> bytes:
    h, w, _ = img.shape
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nSOFTWARE=goniosim\n\n-Y {h} +X {w}\n".encode("ascii")
    return header + encode_rgbe(img)


def decode_hdr(data: bytes) -> np.ndarray:
    """Read back a flat RGBE file written by `hdr_bytes` (for tests)."""
    end = data.index(b"\n\n") + 2
    res_end = data.index(b"\n", end)
    parts = data[end:res_end].split()
    h, w = int(parts[1]), int(parts[3])
    px = np.frombuffer(data[res_end + 1 : res_end + 1 + h * w * 4], dtype=np.uint8).reshape(h, w, 4).astype(np.float64)
    e = px[..., 3]
    f = np.where(e > 0, np.ldexp(1.0, (e - 136).astype(int)), 0.0)
    return (px[..., :3] + 0.5) * f[..., None] * (e > 0)[..., None]


def exr_bytes_to_file(img: np.ndarray, path: str, half: bool) -> None:
    import OpenEXR  # optional dependency, pinned in sim/requirements.txt

    arr = img.astype(np.float16 if half else np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": arr}) as f:
        f.write(path)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 encoding of linear values in [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def png_bytes(img: np.ndarray, exposure: float, bits: int) -> bytes:
    """An sRGB-encoded RGB PNG (8 or 16 bit) of the linear image times `exposure`: values above
    1 clip at the largest code, NaN and negative values read 0."""
    import struct
    import zlib

    h, w, _ = img.shape
    lin = np.nan_to_num(img * exposure, nan=0.0, posinf=1.0, neginf=0.0)
    top = (1 << bits) - 1
    codes = np.rint(srgb_encode(lin) * top)
    raw = codes.astype(">u2" if bits == 16 else np.uint8).reshape(h, -1)
    rows = b"".join(b"\x00" + raw[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, bits, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(rows, 6)) + chunk(b"IEND", b"")


def write_atomic(path: str, data: bytes, durable: bool = True) -> None:
    """Write to a temporary name in the same directory (fsynced when `durable`), then rename
    into place."""
    d, name = os.path.split(path)
    tmp = os.path.join(d, f".{name}.tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        if durable:
            f.flush()
            os.fsync(f.fileno())
    os.replace(tmp, path)
