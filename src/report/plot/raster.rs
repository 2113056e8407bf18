//! Minimal RGB rasteriser for the PNG backend.
//!
//! Plots only need straight lines, filled rectangles and dots, and bitmap
//! text, so a tiny canvas with Bresenham lines (no anti-aliasing) is enough.
//! Line segments are clipped in floating point first, so wild data values far
//! outside the axes never produce endless pixel loops.

use super::font;
use super::{Anchor, Dash, Label, Prim, Rgb};

/// An RGB8 image plus an optional clip box `[x0, y0, x1, y1]` (inclusive).
pub(super) struct Canvas {
    pub(super) w: u32,
    pub(super) h: u32,
    /// Row-major RGB bytes, `3 * w * h` long.
    pub(super) px: Vec<u8>,
    clip: Option<[i64; 4]>,
}

impl Canvas {
    /// White canvas of the given size.
    pub(super) fn new(w: u32, h: u32) -> Self {
        let px = vec![255; 3 * w as usize * h as usize];
        Canvas {
            w,
            h,
            px,
            clip: None,
        }
    }

    /// Colour at (x, y); used by tests.
    #[cfg(test)]
    pub(super) fn get(&self, x: u32, y: u32) -> Rgb {
        let i = 3 * (y as usize * self.w as usize + x as usize);
        Rgb(self.px[i], self.px[i + 1], self.px[i + 2])
    }

    /// Copy `other` onto this canvas with its top-left corner at (`x0`, `y0`), cut at the
    /// edges (a panel into the image of [`super::Panels`]).
    pub(super) fn blit(&mut self, other: &Canvas, x0: u32, y0: u32) {
        let w = other.w.min(self.w.saturating_sub(x0)) as usize;
        for y in 0..other.h.min(self.h.saturating_sub(y0)) {
            let src = 3 * (y as usize * other.w as usize);
            let dst = 3 * ((y0 + y) as usize * self.w as usize + x0 as usize);
            self.px[dst..dst + 3 * w].copy_from_slice(&other.px[src..src + 3 * w]);
        }
    }

    /// Drawable box: the clip box, or the whole image.
    fn bounds(&self) -> [i64; 4] {
        let (w, h) = (i64::from(self.w) - 1, i64::from(self.h) - 1);
        match self.clip {
            Some([x0, y0, x1, y1]) => [x0.max(0), y0.max(0), x1.min(w), y1.min(h)],
            None => [0, 0, w, h],
        }
    }

    /// Fill the inclusive box `[x0, y0, x1, y1]`, limited to the bounds.
    fn fill(&mut self, r: [i64; 4], c: Rgb) {
        let [bx0, by0, bx1, by1] = self.bounds();
        for y in r[1].max(by0)..=r[3].min(by1) {
            for x in r[0].max(bx0)..=r[2].min(bx1) {
                let i = 3 * (y as usize * self.w as usize + x as usize);
                self.px[i..i + 3].copy_from_slice(&[c.0, c.1, c.2]);
            }
        }
    }

    /// Draw a segment `width` pixels thick (a square brush on a Bresenham path).
    fn line(&mut self, a: (f64, f64), b: (f64, f64), width: f64, c: Rgb) {
        let [x0, y0, x1, y1] = self.bounds().map(|v| v as f64);
        let Some((a, b)) = clip_segment(a, b, [x0 - 2.0, y0 - 2.0, x1 + 2.0, y1 + 2.0]) else {
            return;
        };
        let brush = (width.round() as i64).clamp(1, 4);
        let off = (brush - 1) / 2;
        let (mut x, mut y) = (a.0.round() as i64, a.1.round() as i64);
        let (xe, ye) = (b.0.round() as i64, b.1.round() as i64);
        let (dx, dy) = ((xe - x).abs(), -(ye - y).abs());
        let (sx, sy) = ((xe - x).signum(), (ye - y).signum());
        let mut err = dx + dy;
        loop {
            let (bx, by) = (x - off, y - off);
            self.fill([bx, by, bx + brush - 1, by + brush - 1], c);
            if x == xe && y == ye {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Polyline through `part`: solid, or dashed with `[on, off]` pixels
    /// measured along the polyline from its start (as SVG draws a subpath).
    /// Dashes are split off after clipping each segment, so a segment far
    /// outside the canvas costs no more than one inside it.
    fn polyline(&mut self, part: &[(f64, f64)], width: f64, c: Rgb, dash: Dash) {
        let Some([on, off]) = dash else {
            for w in part.windows(2) {
                self.line(w[0], w[1], width, c);
            }
            return;
        };
        let [x0, y0, x1, y1] = self.bounds().map(|v| v as f64);
        let bx = [x0 - 2.0, y0 - 2.0, x1 + 2.0, y1 + 2.0];
        let (period, mut done) = (on + off, 0.0); // `done`: length before segment
        for w in part.windows(2) {
            let (a, b) = (w[0], w[1]);
            if let Some((p, q)) = clip_segment(a, b, bx) {
                let len = (q.0 - p.0).hypot(q.1 - p.1);
                let at = |s: f64| (p.0 + (q.0 - p.0) * s / len, p.1 + (q.1 - p.1) * s / len);
                // Start of the current period, relative to `p` (at most 0).
                let phase = (done + (p.0 - a.0).hypot(p.1 - a.1)).rem_euclid(period);
                let mut s = if phase.is_finite() { -phase } else { 0.0 };
                while s < len {
                    let (s0, s1) = (s.max(0.0), (s + on).min(len));
                    if s1 > s0 {
                        self.line(at(s0), at(s1), width, c);
                    }
                    s += period;
                }
            }
            done += (b.0 - a.0).hypot(b.1 - a.1);
        }
    }

    /// Filled disc of radius `r` centred at `(cx, cy)`, or with `ring` only
    /// its 1 px wide rim (the pixels at distance `r` +- 0.5).
    fn dot(&mut self, cx: f64, cy: f64, r: f64, ring: bool, c: Rgb) {
        if !(cx.is_finite() && cy.is_finite()) {
            return;
        }
        let (x, y, ri) = (cx.round() as i64, cy.round() as i64, r.ceil() as i64);
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                let d2 = (dx * dx + dy * dy) as f64;
                let on = if ring {
                    (d2.sqrt() - r).abs() <= 0.5
                } else {
                    d2 <= r * r + 0.5 * r
                };
                if on {
                    self.fill([x + dx, y + dy, x + dx, y + dy], c);
                }
            }
        }
    }

    /// Bitmap text; `(x, y)` is the anchor point, `y` the vertical centre of
    /// the glyph box (for vertical text: `x` is the centre, `y` the anchor).
    fn text(&mut self, t: &Label) {
        let ascii = font::to_ascii(&t.text);
        let sc = i64::from(t.scale);
        let width = f64::from(font::text_width(&ascii, t.scale));
        let shift = match t.anchor {
            Anchor::Start => 0.0,
            Anchor::Middle => width / 2.0,
            Anchor::End => width,
        };
        let half_h = f64::from(font::GLYPH_H * t.scale) / 2.0;
        // Device position of the top-left corner of the first glyph (as read).
        let (ox, oy) = if t.vertical {
            ((t.x - half_h).round() as i64, (t.y + shift).round() as i64)
        } else {
            ((t.x - shift).round() as i64, (t.y - half_h).round() as i64)
        };
        // Bold: each glyph pixel is one device pixel wider along the text.
        let wide = if t.bold { sc + 1 } else { sc };
        for (k, ch) in ascii.chars().enumerate() {
            let base = k as i64 * i64::from(font::ADVANCE) * sc;
            for (gx, col) in font::glyph(ch).iter().enumerate() {
                for gy in (0..i64::from(font::GLYPH_H)).filter(|gy| col >> gy & 1 == 1) {
                    // Text-space block: u along the text, v downwards.
                    let (u, v) = (base + gx as i64 * sc, gy * sc);
                    if t.vertical {
                        // Rotated 90 degrees counter-clockwise: u points up.
                        self.fill(
                            [ox + v, oy - u - wide + 1, ox + v + sc - 1, oy - u],
                            t.color,
                        );
                    } else {
                        self.fill(
                            [ox + u, oy + v, ox + u + wide - 1, oy + v + sc - 1],
                            t.color,
                        );
                    }
                }
            }
        }
    }

    /// Draw one scene primitive; `frame` is the plot box data is clipped to.
    pub(super) fn draw(&mut self, p: &Prim, frame: [f64; 4]) {
        let frame = Some(frame.map(|v| v.round() as i64));
        self.clip = None;
        match p {
            Prim::Path(parts, color, width, dash) => {
                self.clip = frame;
                for part in parts {
                    self.polyline(part, *width, *color, *dash);
                    if let [only] = part.as_slice() {
                        self.dot(only.0, only.1, 1.0, false, *color);
                    }
                }
            }
            Prim::Line(a, b, color, width, dash) => self.polyline(&[*a, *b], *width, *color, *dash),
            Prim::Rect(r, fill, stroke) => {
                let [l, t, r, b] = r.map(f64::round);
                if let Some(f) = fill {
                    self.fill([l, t, r, b].map(|v| v as i64), *f);
                }
                if let Some(s) = stroke {
                    let corners = [(l, t), (r, t), (r, b), (l, b), (l, t)];
                    for w in corners.windows(2) {
                        self.line(w[0], w[1], 1.0, *s);
                    }
                }
            }
            Prim::Dots(pts, color, r, ring, clip) => {
                self.clip = if *clip { frame } else { None };
                for &(x, y) in pts {
                    self.dot(x, y, *r, *ring, *color);
                }
            }
            Prim::Text(t) => self.text(t),
        }
        self.clip = None;
    }
}

/// Liang-Barsky clipping of segment a-b to the box `[x0, y0, x1, y1]`.
pub(super) fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    bx: [f64; 4],
) -> Option<((f64, f64), (f64, f64))> {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return None;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (p, q) in [
        (-dx, a.0 - bx[0]),
        (dx, bx[2] - a.0),
        (-dy, a.1 - bx[1]),
        (dy, bx[3] - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            t0 = t0.max(q / p);
        } else {
            t1 = t1.min(q / p);
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}
