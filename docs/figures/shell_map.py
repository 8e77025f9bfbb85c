#!/usr/bin/env python3
"""Draws docs/shell_map.svg: the shell map of a curved base mesh, in world and in texel space.

A 2D cross-section of the map in common/shell_map.h. Each base segment (a triangle seen edge-on)
has corners P_a, P_b with unit vertex normals N_a, N_b; its prism maps

    world(s, h) = (1 - s)(P_a - h N_a) + s (P_b - h N_b)
    texel(s, h) = ((k + s) W, D (1 - h / depth))          (segment k, one tile per segment)

A straight world ray is marched as the renderer does: at each sample the map is inverted by Newton
in the current prism (moving to the neighbour across a shared side face), the tile's distance is
read there and the ray steps dt = distance / |J r|, J = d texel / d world. The curve in texel space
is the image of that straight ray; the dashed line is the planar approximation (GPU Gems 2 ch. 8):
the ray mapped once with the Jacobian at its entry and followed straight.

Standard library only. Run from anywhere: python3 docs/figures/shell_map.py
"""

import math
import os
import re

# ---------------------------------------------------------------------------------------------
# Geometry (world units, y up)
# ---------------------------------------------------------------------------------------------

RADIUS = 1.0                    # the base surface: an arc of a circle centred at the origin
ARC_DEGREES = (-46.0, 46.0)     # angles from the vertical (+y) of the first and last vertex
SEGMENTS = 4
DEPTH = 0.25                    # shell depth, world units

TILE_W = 12.0                   # texels along the tile (one tile per segment: the tile repeats)
TILE_D = 16.0                   # D: texel z of the top

# The detail: one bump per tile (a disc centred on the floor), distances in texels.
BUMP_X = 0.5 * TILE_W
BUMP_R = 0.36 * TILE_D


def vertex(i):
    a = math.radians(ARC_DEGREES[0] + (ARC_DEGREES[1] - ARC_DEGREES[0]) * i / SEGMENTS)
    n = (math.sin(a), math.cos(a))
    return (RADIUS * n[0], RADIUS * n[1]), n


VERTICES = [vertex(i) for i in range(SEGMENTS + 1)]


def world_at(k, s, h):
    (pa, na), (pb, nb) = VERTICES[k], VERTICES[k + 1]
    return ((1 - s) * (pa[0] - h * na[0]) + s * (pb[0] - h * nb[0]),
            (1 - s) * (pa[1] - h * na[1]) + s * (pb[1] - h * nb[1]))


def world_jacobian(k, s, h):
    """Columns d world / ds, d world / dh."""
    (pa, na), (pb, nb) = VERTICES[k], VERTICES[k + 1]
    ds = (pb[0] - h * nb[0] - pa[0] + h * na[0], pb[1] - h * nb[1] - pa[1] + h * na[1])
    n = ((1 - s) * na[0] + s * nb[0], (1 - s) * na[1] + s * nb[1])
    return ds, (-n[0], -n[1])


def solve2(c0, c1, v):
    """(x, y) with x c0 + y c1 = v."""
    det = c0[0] * c1[1] - c0[1] * c1[0]
    return ((v[0] * c1[1] - v[1] * c1[0]) / det, (c0[0] * v[1] - c0[1] * v[0]) / det)


def invert(k, p, guess=(0.5, 0.0)):
    """(s, h) with world_at(k, s, h) = p, by Newton."""
    s, h = guess
    for _ in range(30):
        w = world_at(k, s, h)
        c0, c1 = world_jacobian(k, s, h)
        ds, dh = solve2(c0, c1, (p[0] - w[0], p[1] - w[1]))
        s, h = s + ds, h + dh
        if abs(ds) + abs(dh) < 1e-13:
            break
    return s, h


def texel_at(k, s, h):
    return ((k + s) * TILE_W, TILE_D * (1 - h / DEPTH))


def texel_velocity(k, s, h, r):
    """J r: d texel / dt along the world direction r."""
    c0, c1 = world_jacobian(k, s, h)
    ds, dh = solve2(c0, c1, r)
    return ds * TILE_W, -dh * TILE_D / DEPTH


def tile_distance(x, z):
    """The tile's distance (texels): the floor z = 0 and one disc per tile, repeating in x."""
    u = (x % TILE_W) - BUMP_X
    return min(z, math.hypot(u, z) - BUMP_R)


def locate(p, k, guess):
    """The prism holding world point p, starting at prism k; moves across shared side faces."""
    for _ in range(SEGMENTS + 1):
        s, h = invert(k, p, guess)
        if s < 0 and k > 0:
            k, guess = k - 1, (1.0, h)
        elif s > 1 and k < SEGMENTS - 1:
            k, guess = k + 1, (0.0, h)
        else:
            return k, s, h
    return k, s, h


def top_crossing(t0, t1):
    """The first (t, prism) with t in (t0, t1] where the ray crosses the top (h = 0) of a prism."""
    crossings = []
    for k in range(SEGMENTS):
        (pa, _), (pb, _) = VERTICES[k], VERTICES[k + 1]
        e = (pb[0] - pa[0], pb[1] - pa[1])
        # ray_at(t) = pa + s e
        t, s = solve2(RAY_DIR, (-e[0], -e[1]), (pa[0] - RAY_ORIGIN[0], pa[1] - RAY_ORIGIN[1]))
        if 0 <= s <= 1 and t0 < t <= t1:
            crossings.append((t, k))
    return min(crossings)


# The camera ray: enters the top of prism 0 and grazes the shell.
ENTRY_PRISM, ENTRY_S = 0, 0.4
RAY_DEGREES = 6.0               # direction above the horizontal, world
_entry = world_at(ENTRY_PRISM, ENTRY_S, 0.0)
RAY_DIR = (math.cos(math.radians(RAY_DEGREES)), math.sin(math.radians(RAY_DEGREES)))
RAY_BACK = 0.3                  # how far back the camera is drawn (world units)
RAY_ORIGIN = (_entry[0] - RAY_BACK * RAY_DIR[0], _entry[1] - RAY_BACK * RAY_DIR[1])


def ray_at(t):
    return (RAY_ORIGIN[0] + t * RAY_DIR[0], RAY_ORIGIN[1] + t * RAY_DIR[1])


def march():
    """Sphere tracing through the shell, as the renderer does. Returns the samples
    (t, prism, s, h), the exit t and how the ray ended ('top' or 'hit')."""
    t = RAY_BACK
    k, guess = ENTRY_PRISM, (ENTRY_S, 0.0)
    samples = []
    for _ in range(200):
        k, s, h = locate(ray_at(t), k, guess)
        guess = (s, h)
        if h < -1e-9:   # above the top: the ray left through the top of prism k
            return samples, top_crossing(samples[-1][0], t), 'top'
        w = world_at(k, s, h)
        assert math.dist(w, ray_at(t)) < 1e-12, 'the map was not inverted'
        samples.append((t, k, s, h))
        x, z = texel_at(k, s, h)
        distance = tile_distance(x, z)
        if distance < 1e-3:
            return samples, (t, k), 'hit'
        vx, vz = texel_velocity(k, s, h, RAY_DIR)
        t += distance / math.hypot(vx, vz)
    raise RuntimeError('march did not end')


SAMPLES, (EXIT_T, EXIT_PRISM), ENDING = march()
assert ENDING == 'top', 'the figure wants a grazing ray that leaves through the top'
assert EXIT_PRISM > ENTRY_PRISM, 'the figure wants the ray to cross a shared side face'


def true_path(steps=400):
    """The texel-space image of the straight world ray, entry to exit, as (x, z) points."""
    points, k, guess = [], ENTRY_PRISM, (ENTRY_S, 0.0)
    for i in range(steps + 1):
        t = RAY_BACK + (EXIT_T - RAY_BACK) * i / steps
        k, s, h = locate(ray_at(t), k, guess)
        guess = (s, h)
        points.append(texel_at(k, s, max(h, 0.0)))
    return points


def planar_march():
    """Ch. 8: the ray mapped into texel space once, with the Jacobian at its entry, and sphere
    traced along that straight line. Returns its samples (texel x, z); the last is its hit."""
    x0, z0 = texel_at(ENTRY_PRISM, ENTRY_S, 0.0)
    vx, vz = texel_velocity(ENTRY_PRISM, ENTRY_S, 0.0, RAY_DIR)
    speed = math.hypot(vx, vz)
    ux, uz = vx / speed, vz / speed
    points, t = [], 0.0
    for _ in range(200):
        x, z = x0 + t * ux, z0 + t * uz
        points.append((x, z))
        d = tile_distance(x, z)
        if d < 1e-3:
            return points
        t += d
    raise RuntimeError('planar march did not end')


# ---------------------------------------------------------------------------------------------
# Drawing
# ---------------------------------------------------------------------------------------------

WIDTH, HEIGHT = 900, 420
NORMAL_LENGTH = 0.13            # world units, as drawn
RAY_BEYOND = 0.2                # world units drawn past the exit
FONT = "DejaVu Sans, Helvetica, Arial, sans-serif"
INK = "#222"
MUTED = "#666"
PRISM_FILL = "#e6eef7"
PRISM_EDGE = "#7d93ad"
DETAIL_FILL = "#c9ccd1"
RAY = "#1f5fbf"
PLANAR = "#d2691e"
NORMAL = "#2e8b57"
HALO = {"stroke": "white", "stroke_width": 3, "paint_order": "stroke", "stroke_linejoin": "round"}


class Svg:
    def __init__(self):
        self.parts = []

    def add(self, text):
        self.parts.append(text)

    def path(self, points, close=False, **style):
        d = "M" + " L".join(f"{x:.2f},{y:.2f}" for x, y in points) + (" Z" if close else "")
        self.add(f'<path d="{d}"{attrs(style)}/>')

    def line(self, a, b, **style):
        self.add(f'<line x1="{a[0]:.2f}" y1="{a[1]:.2f}" x2="{b[0]:.2f}" y2="{b[1]:.2f}"'
                 f'{attrs(style)}/>')

    def circle(self, c, r, **style):
        self.add(f'<circle cx="{c[0]:.2f}" cy="{c[1]:.2f}" r="{r}"{attrs(style)}/>')

    def text(self, p, content, size=13, anchor="start", fill=INK, **style):
        self.add(f'<text x="{p[0]:.1f}" y="{p[1]:.1f}" font-size="{size}" text-anchor="{anchor}"'
                 f' fill="{fill}"{attrs(style)}>{content}</text>')

    def arrow(self, a, b, color, width=1.6, head=7.0, **style):
        dx, dy = b[0] - a[0], b[1] - a[1]
        n = math.hypot(dx, dy)
        ux, uy = dx / n, dy / n
        base = (b[0] - head * ux, b[1] - head * uy)
        self.line(a, base, stroke=color, stroke_width=width, **style)
        left = (base[0] - 0.45 * head * uy, base[1] + 0.45 * head * ux)
        right = (base[0] + 0.45 * head * uy, base[1] - 0.45 * head * ux)
        self.path([b, left, right], close=True, fill=color)

    def cross(self, c, r, color, width=2.2):
        self.line((c[0] - r, c[1] - r), (c[0] + r, c[1] + r), stroke=color, stroke_width=width)
        self.line((c[0] - r, c[1] + r), (c[0] + r, c[1] - r), stroke=color, stroke_width=width)

    def document(self):
        return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}"'
                f' viewBox="0 0 {WIDTH} {HEIGHT}" font-family="{FONT}">\n'
                f'<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>\n'
                + "\n".join(self.parts) + "\n</svg>\n")


def attrs(style):
    """Keyword styles as SVG attributes: stroke_width -> stroke-width."""
    return "".join(f' {k.replace("_", "-")}="{v}"' for k, v in style.items())


def sub(text, size=10, shift=3.5):
    """SVG text with TeX-like subscripts: 'P_0' and 'b_i' get their one-character index below
    (by dy, which every SVG renderer honours; the text after it moves back up)."""
    pieces = re.split(r"_(\w)", text)      # text, index, text, index, ..., text
    out = [pieces[0]]
    for index, after in zip(pieces[1::2], pieces[2::2]):
        out.append(f'<tspan font-size="{size}" dy="{shift}">{index}</tspan>')
        if after:
            out.append(f'<tspan dy="{-shift}" xml:space="preserve">{after}</tspan>')
    return "".join(out)


class WorldView:
    """World units to pixels: uniform scale, the bounds centred in the box, y down."""

    def __init__(self, box, bounds):
        (x0, y0, x1, y1), ((bx0, by0), (bx1, by1)) = box, bounds
        self.scale = min((x1 - x0) / (bx1 - bx0), (y1 - y0) / (by1 - by0))
        self.ox = 0.5 * (x0 + x1) - self.scale * 0.5 * (bx0 + bx1)
        self.oy = 0.5 * (y0 + y1) + self.scale * 0.5 * (by0 + by1)

    def __call__(self, p):
        return (self.ox + self.scale * p[0], self.oy - self.scale * p[1])


class TexelView:
    """Texel (x, z) to pixels: the SEGMENTS tiles side by side between x0 and x1, z = D at y_top
    and z = 0 at y_floor."""

    def __init__(self, x0, x1, y_top, y_floor):
        self.x0, self.sx = x0, (x1 - x0) / (SEGMENTS * TILE_W)
        self.y_top, self.y_floor = y_top, y_floor

    def __call__(self, p):
        return (self.x0 + self.sx * p[0], self.y_floor + (self.y_top - self.y_floor) * p[1] / TILE_D)


def bump_outline(n=48):
    """One tile's detail (the disc on the floor) as texel (x, z) points, floor to floor."""
    return [(BUMP_X + BUMP_R * math.cos(math.pi * (1 - i / n)),
             BUMP_R * math.sin(math.pi * (1 - i / n))) for i in range(n + 1)]


def prism_of_texel(x, z):
    """(k, s, h) of a texel point (x across the SEGMENTS tiles)."""
    k = min(max(int(x // TILE_W), 0), SEGMENTS - 1)
    return k, x / TILE_W - k, DEPTH * (1 - z / TILE_D)


def draw_world(svg, box):
    corners = [p for p, _ in VERTICES] + [world_at(k, s, DEPTH) for k in range(SEGMENTS) for s in (0, 1)]
    corners += [RAY_ORIGIN, ray_at(EXIT_T + RAY_BEYOND)]
    bounds = ((min(p[0] for p in corners), min(p[1] for p in corners)),
              (max(p[0] for p in corners), max(p[1] for p in corners) + 0.17))
    wv = WorldView(box, bounds)

    for k in range(SEGMENTS):
        quad = [world_at(k, 0, 0), world_at(k, 1, 0), world_at(k, 1, DEPTH), world_at(k, 0, DEPTH)]
        svg.path([wv(p) for p in quad], close=True, fill=PRISM_FILL)
        bump = [world_at(*prism_of_texel(k * TILE_W + x, z)) for x, z in bump_outline()]
        svg.path([wv(p) for p in bump], close=True, fill=DETAIL_FILL)
    for k in range(SEGMENTS):
        svg.line(wv(world_at(k, 0, DEPTH)), wv(world_at(k, 1, DEPTH)), stroke=PRISM_EDGE,
                 stroke_width=1.5)
    for i in range(SEGMENTS + 1):   # side faces, each shared by two neighbouring prisms
        k, s = (i, 0) if i < SEGMENTS else (SEGMENTS - 1, 1)
        svg.line(wv(world_at(k, s, 0)), wv(world_at(k, s, DEPTH)), stroke=PRISM_EDGE,
                 stroke_width=1.2)
    for k in range(SEGMENTS):
        svg.line(wv(world_at(k, 0, 0)), wv(world_at(k, 1, 0)), stroke=INK, stroke_width=2.2)

    for i, (p, n) in enumerate(VERTICES):
        tip = (p[0] + NORMAL_LENGTH * n[0], p[1] + NORMAL_LENGTH * n[1])
        svg.arrow(wv(p), wv(tip), NORMAL, width=1.6)
        svg.circle(wv(p), 2.6, fill=INK)
        t = wv((p[0] + (NORMAL_LENGTH + 0.045) * n[0], p[1] + (NORMAL_LENGTH + 0.045) * n[1]))
        svg.text((t[0], t[1] + 5), sub(f"N_{i}"), fill=NORMAL, anchor="middle")
        q = wv(p)
        if i == 0:
            svg.text((q[0] + 4, q[1] + 18), sub("P_0"))
        elif i < SEGMENTS:
            svg.text((q[0] - 7, q[1] - 5), sub(f"P_{i}"), anchor="end")
        else:
            svg.text((q[0] + 7, q[1] + 12), sub(f"P_{i}"))

    # ch. 8's straight texel line, taken back to world space through the shell map
    planar = planar_march()
    dense = []
    for (xa, za), (xb, zb) in zip(planar, planar[1:]):
        for j in range(8):
            f = j / 8
            dense.append(wv(world_at(*prism_of_texel(xa + f * (xb - xa), za + f * (zb - za)))))
    dense.append(wv(world_at(*prism_of_texel(*planar[-1]))))
    svg.path(dense, fill="none", stroke=PLANAR, stroke_width=1.8, stroke_dasharray="6 4")
    svg.cross(dense[-1], 4.5, PLANAR)

    exit_ = wv(ray_at(EXIT_T))
    svg.line(wv(RAY_ORIGIN), exit_, stroke=RAY, stroke_width=2.2)
    svg.arrow(exit_, wv(ray_at(EXIT_T + RAY_BEYOND)), RAY, width=2.2, head=9)
    svg.circle(wv(RAY_ORIGIN), 4.5, fill="white", stroke=RAY, stroke_width=2)
    for t, _, _, _ in SAMPLES:
        svg.circle(wv(ray_at(t)), 3.4, fill=RAY, stroke="white", stroke_width=1)
    return wv, exit_


def draw_texel(svg, tv):
    for k in range(SEGMENTS):
        x0, x1 = k * TILE_W, (k + 1) * TILE_W
        svg.path([tv((x0, TILE_D)), tv((x1, TILE_D)), tv((x1, 0)), tv((x0, 0))], close=True,
                 fill=PRISM_FILL)
        svg.path([tv((k * TILE_W + x, z)) for x, z in bump_outline()], close=True, fill=DETAIL_FILL)
    svg.line(tv((0, 0)), tv((SEGMENTS * TILE_W, 0)), stroke=PRISM_EDGE, stroke_width=1.5)
    for k in range(SEGMENTS + 1):
        svg.line(tv((k * TILE_W, 0)), tv((k * TILE_W, TILE_D)), stroke=PRISM_EDGE, stroke_width=1.2)
    svg.line(tv((0, TILE_D)), tv((SEGMENTS * TILE_W, TILE_D)), stroke=INK, stroke_width=2.2)

    planar = planar_march()
    svg.line(tv(planar[0]), tv(planar[-1]), stroke=PLANAR, stroke_width=2, stroke_dasharray="6 4")
    svg.cross(tv(planar[-1]), 4.5, PLANAR)

    svg.path([tv(p) for p in true_path()], fill="none", stroke=RAY, stroke_width=2.4)
    for t, k, s, h in SAMPLES:
        svg.circle(tv(texel_at(k, s, h)), 3.4, fill=RAY, stroke="white", stroke_width=1)
    return planar


def leader(svg, text_at, target, text, anchor="start", fill=INK, start=None):
    """A label and a thin line from `start` (default: the text's baseline start) to what it names."""
    svg.line(start or (text_at[0], text_at[1] - 4), target, stroke=MUTED, stroke_width=0.8)
    svg.text(text_at, sub(text), anchor=anchor, fill=fill)


def draw():
    svg = Svg()
    split = 486                      # the panels' border
    left, right = 22, split + 24

    svg.text((left, 30), "World space", size=15, font_weight="bold")
    svg.text((left, 49), "a cross-section of the curved base mesh and its shell", fill=MUTED)
    wv, exit_ = draw_world(svg, (left + 20, 60, split - 16, 300))
    svg.line((split, 18), (split, 345), stroke="#ddd", stroke_width=1)

    svg.text((right, 30), "Texel space of the tile", size=15, font_weight="bold")
    svg.text((right, 49), "the same prisms, one tile each (the tile repeats)", fill=MUTED)
    x0, x1, y_top = right + 44, WIDTH - 18, 122
    tv = TexelView(x0, x1, y_top, y_top + (x1 - x0) * TILE_D / (SEGMENTS * TILE_W))
    planar = draw_texel(svg, tv)

    # world-space labels
    o = wv(RAY_ORIGIN)
    svg.text((left, o[1] + 24), "camera", fill=RAY)
    top_mid = wv(world_at(0, 0.35, 0))
    leader(svg, (left, 92), (top_mid[0] - 2, top_mid[1] - 3), "top: the base triangles (z = D)",
           start=(left + 70, 96))
    bottom_mid = wv(world_at(0, 0.45, DEPTH))
    leader(svg, (left, 296), (bottom_mid[0] - 2, bottom_mid[1] + 2),
           "bottom: P_i moved depth along −N_i (z = 0)", start=(left + 110, 284))
    side_low = wv(world_at(1, 0, 0.85 * DEPTH))
    leader(svg, (left + 200, 262), (side_low[0] + 2, side_low[1] + 2), "shared side face",
           start=(left + 222, 250))
    leader(svg, (split - 10, 96), (exit_[0] + 2, exit_[1] - 4), "leaves through the top",
           anchor="end", fill=RAY, start=(split - 40, 100))

    planar_hit = wv(world_at(*prism_of_texel(*planar[-1])))
    svg.text((planar_hit[0] + 8, planar_hit[1] + 17), "planar (ch. 8)", fill=PLANAR, **HALO)

    # texel-space labels
    top, floor = tv((0, TILE_D)), tv((0, 0))
    detail = tv(((SEGMENTS - 0.5) * TILE_W, BUMP_R + 0.2 * TILE_D))
    svg.text(detail, "tile detail", anchor="middle", fill=MUTED)
    svg.text((top[0] - 8, top[1] + 5), "z = D", anchor="end")
    svg.text((floor[0] - 8, floor[1] + 5), "z = 0", anchor="end")
    on_curve = tv(texel_at(*SAMPLES[-3][1:]))
    leader(svg, (x1, 100), (on_curve[0] + 2, on_curve[1] - 3), "shell map: the ray’s true path",
           anchor="end", fill=RAY, start=(x1 - 60, 104))
    hit = tv(planar[-1])
    leader(svg, (x0, floor[1] + 42), (hit[0] - 3, hit[1] + 4),
           "planar (ch. 8): straight from the entry", fill=PLANAR, start=(x0 + 60, floor[1] + 30))
    svg.text((x0, floor[1] + 60), "ends on the detail: a false hit", fill=PLANAR)
    svg.text((x1, floor[1] + 18), "x along the tile →", anchor="end", fill=MUTED)

    # captions
    y = 332
    svg.text((left, y), sub("world(b, h) = Σ b_i (P_i − h N_i)"), size=14)
    svg.text((left, y + 19), sub("b: barycentrics; h ∈ [0, depth] below the top"), fill=MUTED)
    svg.text((right, y), sub("texel(b, h) = (uv(b) · uvScale · (W, H), z)"), size=14)
    svg.text((right, y + 19), sub("z = D (1 − h / depth);  uv(b) = Σ b_i uv_i"), fill=MUTED)

    svg.line((left, 364), (WIDTH - 18, 364), stroke="#ddd", stroke_width=1)
    svg.text((left, 384), "Dots: the march’s samples, the same in both panels. At each, the map is inverted "
             "(Newton), the tile’s distance is read there", fill=INK)
    svg.text((left, 404), "and the ray steps dt = distance / |J r| (J = ∂texel / ∂world) along its straight "
             "world path, across shared side faces.", fill=INK)
    return svg


def main():
    out = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir,
                                        "shell_map.svg"))
    with open(out, "w", encoding="utf-8") as f:
        f.write(draw().document())
    print(f"wrote {out}: {len(SAMPLES)} samples, the ray leaves through the top of prism {EXIT_PRISM}")


if __name__ == "__main__":
    main()
