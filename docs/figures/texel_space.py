#!/usr/bin/env python3
"""Draws docs/texel_space.svg: the box of a distance tile in texel space and its axes.

An oblique projection of a W x H x D tile (the depth drawn larger than to scale, so the slab is
visible): x along the tile's width (tangent T, +u), y along its height (bitangent B, +v), z up
through the depth (normal N). z = D is the base surface, where rays enter; z = 0 is the floor.
Dashed copies to the right and behind show that the tile repeats in x and y.

Standard library only. Run from anywhere: python3 docs/figures/texel_space.py
"""

import math
import os

W, H, D = 256.0, 256.0, 16.0
SCALE = 1.15                           # pixels per texel along x
DEPTH_SCALE = 6.0                      # pixels per texel along z (drawn thicker than to scale)
OBLIQUE = (0.55 * math.cos(math.radians(28)), 0.55 * math.sin(math.radians(28)))
ORIGIN = (70.0, 330.0)                # where texel (0, 0, 0) is drawn


def project(x, y, z):
    return (ORIGIN[0] + SCALE * (x + OBLIQUE[0] * y),
            ORIGIN[1] - SCALE * OBLIQUE[1] * y - DEPTH_SCALE * z)


def path(points, close=True):
    text = " ".join(f"{'M' if i == 0 else 'L'}{p[0]:.1f},{p[1]:.1f}" for i, p in enumerate(points))
    return text + (" Z" if close else "")


def box(x0, y0, style):
    corners = lambda z: [project(x0, y0, z), project(x0 + W, y0, z),
                         project(x0 + W, y0 + H, z), project(x0, y0 + H, z)]
    bottom, top = corners(0.0), corners(D)
    parts = [f'<path d="{path(top)}" {style}/>', f'<path d="{path(bottom)}" {style}/>']
    for b, t in zip(bottom, top):
        parts.append(f'<path d="{path([b, t], close=False)}" {style}/>')
    return parts


def arrow(start, end, colour, label, offset=(6, -6), anchor="start"):
    (x0, y0), (x1, y1) = start, end
    angle = math.atan2(y1 - y0, x1 - x0)
    head = [(x1, y1),
            (x1 - 9 * math.cos(angle - 0.4), y1 - 9 * math.sin(angle - 0.4)),
            (x1 - 9 * math.cos(angle + 0.4), y1 - 9 * math.sin(angle + 0.4))]
    return [f'<path d="{path([start, end], close=False)}" stroke="{colour}" stroke-width="2"/>',
            f'<path d="{path(head)}" fill="{colour}" stroke="none"/>',
            f'<text x="{x1 + offset[0]:.1f}" y="{y1 + offset[1]:.1f}" fill="{colour}" '
            f'text-anchor="{anchor}">{label}</text>']


def main():
    out = []
    # Periodic copies first (behind), then the tile.
    ghost = 'fill="none" stroke="#9aa" stroke-width="1" stroke-dasharray="5,4"'
    out += box(W, 0.0, ghost)
    out += box(0.0, H, ghost)
    top = [project(0, 0, D), project(W, 0, D), project(W, H, D), project(0, H, D)]
    bottom = [project(0, 0, 0), project(W, 0, 0), project(W, H, 0), project(0, H, 0)]
    out.append(f'<path d="{path(bottom)}" fill="#d9cfc0" stroke="none"/>')
    out.append(f'<path d="{path(top)}" fill="#cfe3f5" fill-opacity="0.75" stroke="none"/>')
    out += box(0.0, 0.0, 'fill="none" stroke="#234" stroke-width="1.6"')

    # Axes from the origin corner.
    o = project(0, 0, 0)
    out += arrow(o, project(W + 40, 0, 0), "#c0392b", "x (T, +u): 0 … W", (6, 16))
    out += arrow(o, project(0, H + 70, 0), "#27ae60", "y (B, +v): 0 … H", (8, 14))
    out += arrow(o, project(0, 0, D + 16), "#2c5fa8", "z (N): 0 … D", (-4, -8))

    # Face labels.
    p = project(W * 0.62, H * 0.62, D)
    out.append(f'<text x="{p[0]:.1f}" y="{p[1]:.1f}" text-anchor="middle">'
               'z = D: the base surface, rays enter here</text>')
    p = project(W * 0.5, 0, 0)
    out.append(f'<text x="{p[0]:.1f}" y="{p[1] + 20:.1f}" text-anchor="middle">'
               'z = 0: the floor, depth world units below the surface</text>')
    p = project(W * 0.5, 0, D * 0.5)
    out.append(f'<text x="{p[0]:.1f}" y="{p[1] + 5:.1f}" text-anchor="middle">'
               'the detail lives in between (d &lt; 0 inside)</text>')
    p = project(W * 1.55, H * 0.25, D)
    out.append(f'<text x="{p[0]:.1f}" y="{p[1] - 8:.1f}" fill="#688" text-anchor="middle">'
               'repeats in x</text>')
    p = project(W * 0.2, H * 1.75, D)
    out.append(f'<text x="{p[0]:.1f}" y="{p[1] - 8:.1f}" fill="#688" text-anchor="middle">'
               'repeats in y</text>')
    note = ("texel centres at i + 0.5; distances signed, in texels (negative inside); "
            "uv → texel: x = u · uv_scale.x · W, y = v · uv_scale.y · H")
    out.append(f'<text x="20" y="400" font-size="12" fill="#444">{note}</text>')

    svg = ('<svg xmlns="http://www.w3.org/2000/svg" width="860" height="420" '
           'viewBox="0 0 860 420" font-family="sans-serif" font-size="14">\n'
           '<rect width="860" height="420" fill="white"/>\n' + "\n".join(out) + "\n</svg>\n")
    target = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "texel_space.svg")
    with open(target, "w", encoding="utf-8") as file:
        file.write(svg)


if __name__ == "__main__":
    main()
