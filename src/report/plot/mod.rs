//! Small, dependency-free plotting for `clv` reports (SVG and PNG output).
//!
//! The project may not pull in plotting or image crates, yet every analysis
//! needs a figure. This module covers exactly what the reports use: x-y line
//! and point series, step histograms, arrow fields and reference lines, with a
//! framed axis box, "nice" ticks, labels, title and legend; a series' colour and
//! open or filled markers where a figure asks for them; and [`Panels`], several
//! figures in one image.
//!
//! Design: [`Figure`] first computes a layout and a backend-neutral list of
//! primitives in pixel coordinates (`scene`); `svg` turns that list into SVG
//! text, `raster` paints it onto an RGB canvas (with the bitmap glyphs from
//! `font`), and `png` encodes the canvas with a hand-written deflate.
//!
//! No data may be hidden, since a figure that looks empty or lacks a curve
//! misleads. Hence the legend (an opaque box) goes into the first inside corner
//! of the axis box that covers no data, or else outside the axis box (see
//! `Figure::layout`), and series that coincide stay visible (see `pen`): the
//! first three are drawn ever thinner, any later ones dashed, each with its
//! own dash pattern, and with ring markers of their own radius; the legend
//! draws every series' sample with its series' pen.
//!
//! ```ignore
//! let mut fig = Figure::new("Lyapunov spectrum").x_label("i").y_label("λ_i");
//! fig.series("N = 100", &idx, &lam, Marker::LinePoints).hline(0.0);
//! fig.save(Path::new("out"), "spectrum")?;
//! ```

mod font;
mod png;
mod raster;
mod svg;
#[cfg(test)]
mod tests;

use std::path::Path;

/// An sRGB colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rgb(u8, u8, u8);

/// Okabe-Ito colour-blind-safe palette, its yellow replaced by Paul Tol's wine (the original,
/// #F0E442, all but vanished on white in thin dashed curves; darkened to olive it looked like
/// the orange beside it in plots of eight series).
const PALETTE: [Rgb; 8] = [
    Rgb(0x00, 0x72, 0xB2), // blue
    Rgb(0xD5, 0x5E, 0x00), // vermillion
    Rgb(0x00, 0x9E, 0x73), // bluish green
    Rgb(0xCC, 0x79, 0xA7), // reddish purple
    Rgb(0xE6, 0x9F, 0x00), // orange
    Rgb(0x56, 0xB4, 0xE9), // sky blue
    Rgb(0x00, 0x00, 0x00), // black
    Rgb(0x88, 0x22, 0x55), // wine
];
const INK: Rgb = Rgb(0x20, 0x20, 0x20);
const GREY: Rgb = Rgb(0x99, 0x99, 0x99);
const WHITE: Rgb = Rgb(0xFF, 0xFF, 0xFF);

/// Horizontal alignment of a text label relative to its anchor point.
#[derive(Clone, Copy, Debug)]
enum Anchor {
    Start,
    Middle,
    End,
}

/// A text label; `(x, y)` is the anchor point on the text's centre line.
struct Label {
    x: f64,
    y: f64,
    text: String,
    /// Bitmap font scale (1 = 5x8 glyphs); SVG uses a matching font size.
    scale: u32,
    anchor: Anchor,
    /// Rotated 90 degrees counter-clockwise (reads bottom to top).
    vertical: bool,
    bold: bool,
    color: Rgb,
}

impl Label {
    /// Horizontal, regular-weight label in the ink colour.
    fn new(x: f64, y: f64, text: &str, scale: u32, anchor: Anchor) -> Self {
        let (vertical, bold, color, text) = (false, false, INK, text.to_string());
        Label {
            x,
            y,
            text,
            scale,
            anchor,
            vertical,
            bold,
            color,
        }
    }
}

/// Dash pattern `[on, off]` in pixels, starting "on" at the start of each
/// line part (as SVG's `stroke-dasharray` without offset); `None` is solid.
type Dash = Option<[f64; 2]>;

/// Backend-neutral drawing primitive in pixel coordinates (y down).
enum Prim {
    /// Data polylines (one per part) with colour, width and dash pattern,
    /// clipped to the frame.
    Path(Vec<Vec<(f64, f64)>>, Rgb, f64, Dash),
    /// Straight line from `a` to `b` with colour, width and dash pattern
    /// (ticks, legend samples).
    Line((f64, f64), (f64, f64), Rgb, f64, Dash),
    /// Rectangle `[x0, y0, x1, y1]` with optional fill and stroke colours.
    Rect([f64; 4], Option<Rgb>, Option<Rgb>),
    /// Point markers with colour and radius: filled dots, or 1 px rings if
    /// the first flag is set; the second flag clips them to the frame.
    Dots(Vec<(f64, f64)>, Rgb, f64, bool, bool),
    Text(Label),
}

/// Radius of point markers in pixels (of the first series, see [`pen`]).
const DOT_R: f64 = 3.0;

/// Length in pixels of a dash pattern's unit (see [`pen`]).
const DASH_UNIT: f64 = 4.0;

/// How one series is drawn, see [`pen`].
#[derive(Clone, Copy, Debug)]
struct Pen {
    /// Change of the line width from the base width of the series' kind
    /// (lines are at least 1 px wide).
    widen: f64,
    /// Dash pattern of lines (arrows: of their shafts).
    dash: Dash,
    /// Radius of point markers.
    dot_r: f64,
    /// Point markers are 1 px rings instead of filled dots.
    ring: bool,
}

/// How series number `k` (in order of addition) of a figure with `n` series
/// is drawn.
///
/// A later series drawn exactly over an earlier one must not hide it. So the
/// first three series are drawn ever thinner: with two or more series the
/// first draws solid lines 1 px wider than the base width of its kind, the
/// second at the base width, the third 1 px narrower (at least 1 px), and
/// filled dots shrink from radius 3 to 2 to 1.5 px.
///
/// Series from the fourth on (`k >= 3`) draw the thinnest lines, dashed:
/// with `u` = 4 px, series `k` draws `(n - k) u` on and `(k - 2) u` off. All
/// these patterns share the period `(n - 2) u` and start "on" at the start
/// of a line, so where lines coincide from their start, series `k` shows in
/// the unit of each period right after the dashes of series `k + 1`, and the
/// third series in the last unit (lines that meet later meet out of step:
/// there the gaps still let lower series show, but without this guarantee).
/// The dashes get shorter series by series, so the legend tells them apart
/// too. Their point markers are 1 px rings of radius `3 + 1.5 (k - 2)` px:
/// around the dots and around each other, never on the same pixel. So any
/// number of coinciding series all stay visible, also in the PNG, whose
/// lines are whole pixels wide. A lone series keeps the base width.
fn pen(k: usize, n: usize) -> Pen {
    let level = k.min(2);
    let widen = if n > 1 { 1.0 } else { 0.0 } - level as f64;
    if k < 3 {
        let dot_r = DOT_R - [0.0, 1.0, 1.5][level];
        return Pen {
            widen,
            dash: None,
            dot_r,
            ring: false,
        };
    }
    let on = DASH_UNIT * n.saturating_sub(k).max(1) as f64;
    Pen {
        widen,
        dash: Some([on, DASH_UNIT * (k - 2) as f64]),
        dot_r: DOT_R + 1.5 * (k - 2) as f64,
        ring: true,
    }
}

/// How an x-y series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// Straight line segments between consecutive points.
    Line,
    /// A filled dot at every point, no line.
    Points,
    /// Line segments plus a dot at every point.
    LinePoints,
    /// Post-step line: horizontal from each point to the next x, then vertical.
    Steps,
    /// A dense cloud of points (an attractor): small grey dots, whatever the series' place,
    /// so that series added after it stay visible on top of it.
    Cloud,
}

/// The most lines a title is wrapped into.
const TITLE_LINES: usize = 4;

/// Base width of arrows in pixels (before [`pen`]): what they point at is the figure's message.
const ARROW_W: f64 = 3.0;

/// Radius of the dots of a [`Marker::Cloud`] in pixels.
const CLOUD_R: f64 = 1.0;

enum Kind {
    /// Points in data order; non-finite points break lines.
    Xy(Vec<(f64, f64)>, Marker),
    /// Arrows as (tail, head) pairs in data coordinates, all finite.
    Arrows(Vec<((f64, f64), (f64, f64))>),
}

struct Series {
    label: String,
    color: Rgb,
    kind: Kind,
    /// Point markers set open (rings) or filled by [`Figure::open_markers`]; None: by the
    /// series' place ([`pen`]).
    open: Option<bool>,
}

/// A 2-D figure: build it with the chained setters, add data, then render
/// with [`Figure::to_svg`], [`Figure::to_png`] or [`Figure::save`].
pub struct Figure {
    title: String,
    w: u32,
    h: u32,
    x_label: String,
    y_label: String,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
    series: Vec<Series>,
    hlines: Vec<f64>,
    /// One data unit is as many pixels along x as along y ([`Figure::equal_aspect`]).
    equal_aspect: bool,
}

/// Pixel rectangle of the plot frame, the data ranges, and the ticks.
struct Layout {
    l: f64,
    t: f64,
    r: f64,
    b: f64,
    x: (f64, f64),
    y: (f64, f64),
    xticks: Vec<(f64, String)>,
    yticks: Vec<(f64, String)>,
    /// Bitmap text scale used for all text.
    scale: u32,
    /// Vertical centre of the x axis label.
    x_label_y: f64,
    /// Legend box `[x0, y0, x1, y1]`, if the figure has a legend.
    legend: Option<[f64; 4]>,
}

impl Layout {
    fn px(&self, x: f64) -> f64 {
        self.l + (x - self.x.0) / (self.x.1 - self.x.0) * (self.r - self.l)
    }
    fn py(&self, y: f64) -> f64 {
        self.b - (y - self.y.0) / (self.y.1 - self.y.0) * (self.b - self.t)
    }
    fn map(&self, p: (f64, f64)) -> (f64, f64) {
        (self.px(p.0), self.py(p.1))
    }
    fn frame(&self) -> [f64; 4] {
        [self.l, self.t, self.r, self.b]
    }
}

const TICK_LEN: f64 = 6.0;

impl Figure {
    /// New empty figure with a title, 900 x 600 pixels.
    pub fn new(title: &str) -> Self {
        Figure {
            title: title.to_string(),
            w: 900,
            h: 600,
            x_label: String::new(),
            y_label: String::new(),
            x_range: None,
            y_range: None,
            series: Vec::new(),
            hlines: Vec::new(),
            equal_aspect: false,
        }
    }

    /// Equal scales on both axes (a geometric picture, where angles must be seen as they
    /// are): the range of the axis that would be drawn with more pixels per unit is widened
    /// about its centre.
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Image size in pixels (clamped to 120..=8000 on each side).
    pub fn size(mut self, w: u32, h: u32) -> Self {
        self.w = w.clamp(120, 8000);
        self.h = h.clamp(120, 8000);
        self
    }

    /// Label below the x axis.
    pub fn x_label(mut self, s: &str) -> Self {
        self.x_label = s.to_string();
        self
    }

    /// Label left of the y axis (drawn vertically).
    pub fn y_label(mut self, s: &str) -> Self {
        self.y_label = s.to_string();
        self
    }

    /// Fixed x range (default: data range with 3% padding). Reversed bounds
    /// are swapped; non-finite bounds fall back to the automatic range.
    pub fn x_range(mut self, lo: f64, hi: f64) -> Self {
        self.x_range = Some((lo, hi));
        self
    }

    /// Fixed y range, same rules as [`Figure::x_range`].
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    fn push(&mut self, label: &str, kind: Kind) -> &mut Self {
        let color = PALETTE[self.series.len() % PALETTE.len()];
        self.series.push(Series {
            label: label.to_string(),
            color,
            kind,
            open: None,
        });
        self
    }

    /// The series added last takes colour `k` of the palette (0 blue, 1 vermillion, 2 bluish
    /// green, 3 reddish purple, 4 orange, 5 sky blue, 6 black, 7 wine; taken modulo 8)
    /// instead of the colour of its place: for one quantity in one colour across figures.
    pub fn color(&mut self, k: usize) -> &mut Self {
        if let Some(s) = self.series.last_mut() {
            s.color = PALETTE[k % PALETTE.len()];
        }
        self
    }

    /// The series added last is drawn in grey: a reference (a bound, a guide to the eye)
    /// rather than data, so that it takes none of the colours that name quantities.
    pub fn grey(&mut self) -> &mut Self {
        if let Some(s) = self.series.last_mut() {
            s.color = GREY;
        }
        self
    }

    /// The point markers of the series added last are open rings (`true`) or filled dots
    /// (`false`), whatever its place (by default the first three series draw dots and later
    /// ones rings, [`pen`]): for a distinction the reader is told of, such as the paper's
    /// open symbols for one method and filled ones for the other. Sizes: see
    /// [`Figure::pens`].
    pub fn open_markers(&mut self, open: bool) -> &mut Self {
        if let Some(s) = self.series.last_mut() {
            s.open = Some(open);
        }
        self
    }

    /// How each series is drawn: [`pen`] by its place, with the markers that
    /// [`Figure::open_markers`] sets. Markers are sized by the series' place among those of
    /// their kind (series without markers counted as `pen` counts them: dots for the first
    /// three, rings after), as `pen` sizes them: filled dots shrink from radius 3 to 2 to
    /// 1.5 px (and stay there), rings grow from 4.5 px by 1.5 px each, so that coinciding
    /// rings never share a pixel and lie around every dot. Where no series sets its markers
    /// this is `pen`'s own rule.
    fn pens(&self) -> Vec<Pen> {
        let n = self.series.len();
        let (mut dots, mut rings) = (0usize, 0usize);
        let mut pens = Vec::with_capacity(n);
        for (k, s) in self.series.iter().enumerate() {
            let mut p = pen(k, n);
            p.ring = s.open.unwrap_or(p.ring);
            p.dot_r = if p.ring {
                rings += 1;
                DOT_R + 1.5 * rings as f64
            } else {
                dots += 1;
                DOT_R - [0.0, 1.0, 1.5][(dots - 1).min(2)]
            };
            pens.push(p);
        }
        pens
    }

    /// Add an x-y series (pairs beyond the shorter slice are ignored).
    /// Colours come from a colour-blind-safe palette in order of addition.
    pub fn series(&mut self, label: &str, xs: &[f64], ys: &[f64], marker: Marker) -> &mut Self {
        let pts = xs.iter().copied().zip(ys.iter().copied()).collect();
        self.push(label, Kind::Xy(pts, marker));
        if let Some(s) = self.series.last_mut().filter(|_| marker == Marker::Cloud) {
            s.color = GREY;
        }
        self
    }

    /// Add arrows from each point of `from` by the vector in `delta`
    /// (pairs with non-finite components are skipped).
    pub fn arrows(&mut self, label: &str, from: &[(f64, f64)], delta: &[(f64, f64)]) -> &mut Self {
        let arrows = from
            .iter()
            .zip(delta)
            .map(|(&(x, y), &(dx, dy))| ((x, y), (x + dx, y + dy)))
            .filter(|&((a, b), (c, d))| [a, b, c, d].iter().all(|v| v.is_finite()))
            .collect();
        self.push(label, Kind::Arrows(arrows))
    }

    /// Add a histogram of `values` with `bins` equal bins on `[lo, hi]`,
    /// drawn as a step outline. Values outside the range or non-finite are
    /// ignored. With `normalised` the heights are a probability density
    /// (count / (number of binned values * bin width)).
    pub fn histogram(
        &mut self,
        label: &str,
        values: &[f64],
        bins: usize,
        lo: f64,
        hi: f64,
        normalised: bool,
    ) -> &mut Self {
        let mut outline = Vec::new();
        if bins > 0 && lo.is_finite() && hi.is_finite() && lo < hi {
            let width = (hi - lo) / bins as f64;
            let mut counts = vec![0.0; bins];
            for &v in values
                .iter()
                .filter(|v| v.is_finite() && **v >= lo && **v <= hi)
            {
                let k = ((v - lo) / width) as usize;
                counts[k.min(bins - 1)] += 1.0;
            }
            let total: f64 = counts.iter().sum();
            if normalised && total > 0.0 {
                counts.iter_mut().for_each(|c| *c /= total * width);
            }
            outline.push((lo, 0.0));
            for (k, &c) in counts.iter().enumerate() {
                outline.push((lo + k as f64 * width, c));
                outline.push((lo + (k + 1) as f64 * width, c));
            }
            outline.push((hi, 0.0));
        }
        self.push(label, Kind::Xy(outline, Marker::Line))
    }

    /// Add a thin grey horizontal reference line at `y` (included in the
    /// automatic y range, so e.g. `hline(0.0)` always shows the zero line).
    pub fn hline(&mut self, y: f64) -> &mut Self {
        self.hlines.push(y);
        self
    }

    /// Render as an SVG 1.1 document.
    pub fn to_svg(&self) -> String {
        let (layout, prims) = self.scene();
        svg::render(self.w, self.h, layout.frame(), &prims)
    }

    /// Render as a PNG file (RGB, 8 bits per channel).
    pub fn to_png(&self) -> Vec<u8> {
        let canvas = self.raster();
        png::encode(canvas.w, canvas.h, &canvas.px)
    }

    /// Write `stem.svg` and `stem.png` into `dir` (created if missing).
    pub fn save(&self, dir: &Path, stem: &str) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join(format!("{stem}.svg")), self.to_svg())?;
        std::fs::write(dir.join(format!("{stem}.png")), self.to_png())?;
        Ok(())
    }

    fn raster(&self) -> raster::Canvas {
        self.raster_preferring(None)
    }

    /// [`Figure::raster`] with the legend at inside corner `corner` where it is free
    /// ([`Figure::layout_preferring`]).
    fn raster_preferring(&self, corner: Option<usize>) -> raster::Canvas {
        let (layout, prims) = self.scene_preferring(corner);
        let mut canvas = raster::Canvas::new(self.w, self.h);
        for p in &prims {
            canvas.draw(p, layout.frame());
        }
        canvas
    }

    /// Finite (min, max) of the data along x (`axis` 0) or y (`axis` 1).
    fn data_bounds(&self, axis: usize) -> Option<(f64, f64)> {
        let mut vals: Vec<f64> = Vec::new();
        for s in &self.series {
            match &s.kind {
                Kind::Xy(pts, _) => vals.extend(
                    pts.iter()
                        .filter(|p| p.0.is_finite() && p.1.is_finite())
                        .map(|p| pick(*p, axis)),
                ),
                Kind::Arrows(a) => {
                    vals.extend(a.iter().flat_map(|&(p, q)| [pick(p, axis), pick(q, axis)]))
                }
            }
        }
        if axis == 1 {
            vals.extend(self.hlines.iter().filter(|y| y.is_finite()));
        }
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo <= hi).then_some((lo, hi))
    }

    /// [`Figure::layout_preferring`] a figure alone uses.
    #[cfg(test)]
    fn layout(&self) -> Layout {
        self.layout_preferring(None)
    }

    /// Layout with the legend placed where it hides no data: the first of
    /// the inside corners top-right, top-left, bottom-right, bottom-left of
    /// the axis box whose legend box (plus a small margin) is crossed by no
    /// line segment and touches no dot of any series. If every corner covers
    /// data, or the legend does not fit inside, the axis box shrinks to make
    /// room for the legend right of it (or below it, if the axis box would
    /// lose more than half its width or the legend is taller than it).
    /// Inside corner `corner` (an index into that order), if free, goes first: sibling
    /// panels put their legends in one corner where they can ([`Panels::legend_corner`]).
    fn layout_preferring(&self, corner: Option<usize>) -> Layout {
        let mut lay = self.frame_layout(0.0, 0.0);
        let Some((lw, lh)) = self.legend_size(lay.scale) else {
            return lay;
        };
        let [l, t, r, b] = lay.frame();
        let free = self.free_corners(&lay, lw, lh);
        if let Some(bx) = corner.and_then(|c| free[c]).or_else(|| free.into_iter().flatten().next()) {
            lay.legend = Some(bx);
            return lay;
        }
        if lw + 12.0 <= (r - l) / 2.0 && lh <= b - t {
            lay = self.frame_layout(lw + 12.0, 0.0);
            let x0 = lay.r + 12.0;
            lay.legend = Some([x0, lay.t, x0 + lw, lay.t + lh]);
        } else {
            lay = self.frame_layout(0.0, lh + 8.0);
            let h = f64::from(self.h);
            let x0 = ((lay.l + lay.r - lw) / 2.0).round().max(4.0);
            lay.legend = Some([x0, h - 8.0 - lh, x0 + lw, h - 8.0]);
        }
        lay
    }

    /// The legend boxes (`lw` x `lh`) at the inside corners top-right, top-left, bottom-right,
    /// bottom-left of `lay`'s axis box, each where it (plus a small margin) is crossed by no
    /// line segment and touches no dot of any series; none where the legend does not fit.
    fn free_corners(&self, lay: &Layout, lw: f64, lh: f64) -> [Option<[f64; 4]>; 4] {
        let [l, t, r, b] = lay.frame();
        if lw + 20.0 > r - l || lh + 20.0 > b - t {
            return [None; 4];
        }
        let mut data = Vec::new();
        for (s, pen) in self.series.iter().zip(self.pens()) {
            series_prims(lay, s, pen, &mut data);
        }
        let (x0, x1, y0, y1) = (l + 10.0, r - 10.0 - lw, t + 10.0, b - 10.0 - lh);
        [(x1, y0), (x0, y0), (x1, y1), (x0, y1)].map(|(x, y)| Some([x, y, x + lw, y + lh]).filter(|&bx| !data.iter().any(|p| covers(p, bx))))
    }

    /// Which inside corners ([`Figure::free_corners`]) could hold the legend; none without a
    /// legend.
    fn legend_corners(&self) -> Option<[bool; 4]> {
        let lay = self.frame_layout(0.0, 0.0);
        let (lw, lh) = self.legend_size(lay.scale)?;
        Some(self.free_corners(&lay, lw, lh).map(|c| c.is_some()))
    }

    /// Frame, ranges and ticks, leaving `right` and `bottom` pixels of the
    /// image free for a legend outside the axis box.
    fn frame_layout(&self, right: f64, bottom: f64) -> Layout {
        let x = axis_range(self.x_range, self.data_bounds(0));
        let y = axis_range(self.y_range, self.data_bounds(1));
        let mut lay = self.frame_geometry(x, y, right, bottom);
        if self.equal_aspect {
            // The frame moves a little with the tick labels of the new ranges: a few rounds.
            for _ in 0..3 {
                let (ux, uy) = ((lay.x.1 - lay.x.0) / (lay.r - lay.l), (lay.y.1 - lay.y.0) / (lay.b - lay.t));
                let widen = |(lo, hi): (f64, f64), half: f64| ((lo + hi) / 2.0 - half, (lo + hi) / 2.0 + half);
                let (x, y) = if ux > uy { (lay.x, widen(lay.y, ux * (lay.b - lay.t) / 2.0)) } else { (widen(lay.x, uy * (lay.r - lay.l) / 2.0), lay.y) };
                lay = self.frame_geometry(x, y, right, bottom);
            }
        }
        lay
    }

    /// Frame and ticks for the data ranges `x` and `y`.
    fn frame_geometry(&self, x: (f64, f64), y: (f64, f64), right: f64, bottom: f64) -> Layout {
        let scale = text_scale(self.w, self.h);
        let ch = f64::from(8 * scale); // text line height in pixels
        let (w, h) = (f64::from(self.w), f64::from(self.h));
        // Room for the title and the x label (height) and the y label (width).
        let room = |s: &String, v: f64| if s.is_empty() { 0.0 } else { v };
        // Lines 1.25 text heights apart, as drawn in [`Figure::scene`].
        let t = room(&self.title, title_height(self.title_lines(scale).len(), ch)).max(16.0);
        let (xl_h, yl_w) = (
            room(&self.x_label, ch + 8.0),
            room(&self.y_label, ch + 10.0),
        );
        let b = (h - (TICK_LEN + 6.0 + ch + xl_h + 10.0) - bottom)
            .round()
            .max(t + 10.0);
        // y ticks: keep labels at least a text line plus some air apart.
        let yticks = fit_ticks(y, b - t, |_| ch + 12.0);
        let label_w = yticks
            .iter()
            .map(|(_, s)| text_w(s, scale))
            .fold(0.0, f64::max);
        let l = (10.0 + yl_w + label_w + 6.0 + TICK_LEN)
            .round()
            .min(w / 2.0);
        let mut r = (w - 24.0 - right).round().max(l + 10.0);
        let xticks = fit_ticks(x, r - l, |s| text_w(s, scale) + 3.0 * ch);
        // Keep the rightmost tick label inside the image.
        if let Some((v, s)) = xticks.last() {
            let px = l + (v - x.0) / (x.1 - x.0) * (r - l);
            let overflow = px + text_w(s, scale) / 2.0 + 4.0 - w;
            if overflow > 0.0 {
                r = (r - overflow).round().max(l + 10.0);
            }
        }
        Layout {
            l,
            t,
            r,
            b,
            x,
            y,
            xticks,
            yticks,
            scale,
            x_label_y: h - bottom - 10.0 - ch / 2.0,
            legend: None,
        }
    }

    /// The title broken at spaces into lines that fit the image's width (none without a
    /// title): a long title is wrapped, never cut at the image's edges.
    fn title_lines(&self, scale: u32) -> Vec<String> {
        let fits = |s: &str| text_w(s, scale) <= f64::from(self.w) - 16.0;
        // A word wider than the image is cut into pieces that fit.
        let mut pieces: Vec<String> = Vec::new();
        for word in self.title.split(' ').filter(|w| !w.is_empty()) {
            let mut piece = String::new();
            for c in word.chars() {
                if !piece.is_empty() && !fits(&format!("{piece}{c}")) {
                    pieces.push(std::mem::take(&mut piece));
                }
                piece.push(c);
            }
            pieces.push(piece);
        }
        let mut lines: Vec<String> = Vec::new();
        for piece in pieces {
            match lines.last_mut() {
                Some(line) if fits(&format!("{line} {piece}")) => {
                    line.push(' ');
                    line.push_str(&piece);
                }
                _ => lines.push(piece),
            }
        }
        // The title must leave the plot its room: the rest of a longer one is cut, marked.
        if lines.len() > TITLE_LINES {
            lines.truncate(TITLE_LINES);
            let last = &mut lines[TITLE_LINES - 1];
            while !last.is_empty() && !fits(&format!("{last}...")) {
                last.pop();
            }
            last.push_str("...");
        }
        lines
    }

    /// Labelled series with their positions; a legend needs two or more.
    fn legend_entries(&self) -> Vec<(usize, &Series)> {
        let entries: Vec<_> = self
            .series
            .iter()
            .enumerate()
            .filter(|(_, s)| !s.label.is_empty())
            .collect();
        if entries.len() < 2 {
            Vec::new()
        } else {
            entries
        }
    }

    /// Width and height of the legend box, if there is a legend.
    fn legend_size(&self, sc: u32) -> Option<(f64, f64)> {
        let entries = self.legend_entries();
        if entries.is_empty() {
            return None;
        }
        let label_w = entries
            .iter()
            .map(|(_, s)| text_w(&s.label, sc))
            .fold(0.0, f64::max);
        let line_h = f64::from(8 * sc) + 6.0;
        Some((
            8.0 + 14.0 * f64::from(sc) + 8.0 + label_w + 8.0,
            6.0 + line_h * entries.len() as f64,
        ))
    }

    /// Layout plus the primitives to draw, in painting order.
    fn scene(&self) -> (Layout, Vec<Prim>) {
        self.scene_preferring(None)
    }

    /// [`Figure::scene`] with the legend at inside corner `corner` where it is free.
    fn scene_preferring(&self, corner: Option<usize>) -> (Layout, Vec<Prim>) {
        let lay = self.layout_preferring(corner);
        let (l, t, r, b, sc) = (lay.l, lay.t, lay.r, lay.b, lay.scale);
        let (w, ch) = (f64::from(self.w), f64::from(8 * sc));
        let text = |x, y, s: &str, anchor| Label::new(x, y, s, sc, anchor);
        let mut prims = Vec::new();
        for &y in self.hlines.iter().filter(|y| y.is_finite()) {
            let py = lay.py(y);
            if py >= t && py <= b {
                prims.push(Prim::Line((l, py), (r, py), GREY, 1.0, None));
            }
        }
        for (s, pen) in self.series.iter().zip(self.pens()) {
            series_prims(&lay, s, pen, &mut prims);
        }
        prims.push(Prim::Rect([l, t, r, b], None, Some(INK)));
        for (v, s) in &lay.xticks {
            let px = lay.px(*v).round();
            prims.push(Prim::Line((px, b), (px, b + TICK_LEN), INK, 1.0, None));
            let y = b + TICK_LEN + 4.0 + ch / 2.0;
            prims.push(Prim::Text(text(px, y, s, Anchor::Middle)));
        }
        for (v, s) in &lay.yticks {
            let py = lay.py(*v).round();
            prims.push(Prim::Line((l - TICK_LEN, py), (l, py), INK, 1.0, None));
            prims.push(Prim::Text(text(l - TICK_LEN - 4.0, py, s, Anchor::End)));
        }
        if !self.x_label.is_empty() {
            let (x, y) = ((l + r) / 2.0, lay.x_label_y);
            prims.push(Prim::Text(text(x, y, &self.x_label, Anchor::Middle)));
        }
        if !self.y_label.is_empty() {
            let mut label = text(
                10.0 + ch / 2.0,
                (t + b) / 2.0,
                &self.y_label,
                Anchor::Middle,
            );
            label.vertical = true;
            prims.push(Prim::Text(label));
        }
        // Centre on the plot frame if the line fits there, else on the image.
        let centre = |line: &str| if text_w(line, sc) < r - l { (l + r) / 2.0 } else { w / 2.0 };
        prims.extend(title_labels(&self.title_lines(sc), sc, centre));
        self.legend(&lay, &mut prims);
        (lay, prims)
    }

    /// Legend entries in the box chosen by [`Figure::layout`], each with a
    /// sample drawn with the series' pen (width, dash pattern, marker).
    fn legend(&self, lay: &Layout, prims: &mut Vec<Prim>) {
        let Some([x0, y0, x1, y1]) = lay.legend else {
            return;
        };
        let sc = lay.scale;
        let line_h = f64::from(8 * sc) + 6.0;
        let sample = 14.0 * f64::from(sc);
        prims.push(Prim::Rect([x0, y0, x1, y1], Some(WHITE), Some(GREY)));
        let pens = self.pens();
        for (row, (k, s)) in self.legend_entries().into_iter().enumerate() {
            let cy = (y0 + 3.0 + line_h * (row as f64 + 0.5)).round();
            let (a, b) = ((x0 + 8.0, cy), (x0 + 8.0 + sample, cy));
            let pen = pens[k];
            let marker = match s.kind {
                Kind::Xy(_, m) => m,
                Kind::Arrows(_) => Marker::Line,
            };
            let dot = vec![((a.0 + b.0) / 2.0, cy)];
            match marker {
                Marker::Points | Marker::LinePoints => prims.push(Prim::Dots(dot, s.color, pen.dot_r, pen.ring, false)),
                Marker::Cloud => prims.push(Prim::Dots(dot, s.color, 2.0 * CLOUD_R, false, false)),
                Marker::Line | Marker::Steps => {}
            }
            if !matches!(marker, Marker::Points | Marker::Cloud) {
                let base = if matches!(s.kind, Kind::Arrows(_)) { ARROW_W } else { 2.0 };
                let width = (base + pen.widen).max(1.0);
                prims.push(Prim::Line(a, b, s.color, width, pen.dash));
            }
            prims.push(Prim::Text(Label::new(
                b.0 + 8.0,
                cy,
                &s.label,
                sc,
                Anchor::Start,
            )));
        }
    }
}

/// Bitmap text scale of an image of `w` x `h` pixels (1 = 5x8 glyphs).
fn text_scale(w: u32, h: u32) -> u32 {
    if w.min(h) < 400 { 1 } else { 2 }
}

/// Height in pixels of a title of `lines` lines of text height `ch`: lines 1.25 text
/// heights apart, as [`title_labels`] draws them.
fn title_height(lines: usize, ch: f64) -> f64 {
    ((1.25 + 1.25 * lines as f64) * ch).round()
}

/// The bold labels of a title's `lines` at text scale `sc`, each centred at `centre(line)`.
fn title_labels(lines: &[String], sc: u32, centre: impl Fn(&str) -> f64) -> Vec<Prim> {
    let ch = f64::from(8 * sc);
    let label = |(i, line): (usize, &String)| {
        let y = (1.25 + 1.25 * i as f64) * ch;
        let mut label = Label::new(centre(line), y.round(), line, sc, Anchor::Middle);
        label.bold = true;
        Prim::Text(label)
    };
    lines.iter().enumerate().map(label).collect()
}

/// The size in pixels of one panel of the reports' [`Panels`]: two to a row are about as
/// wide as one figure.
pub const PANEL: (u32, u32) = (600, 420);

/// Several figures in one image, as the paper's multi-panel figures: a grid of `cols`
/// columns filled row by row (left to right, then top to bottom), each panel a whole
/// [`Figure`] with its own axes, ranges, title and legend, drawn at its own size at the
/// top left of a cell as large as the largest panel, under a title of the whole.
pub struct Panels {
    title: String,
    cols: usize,
    panels: Vec<Figure>,
}

impl Panels {
    /// No panels yet, `cols` (at least 1) to a row.
    pub fn new(title: &str, cols: usize) -> Self {
        Panels { title: title.to_string(), cols: cols.max(1), panels: Vec::new() }
    }

    /// Add a panel, after those added before it in reading order.
    pub fn push(&mut self, fig: Figure) -> &mut Self {
        self.panels.push(fig);
        self
    }

    /// Image size, the title's labels, and each panel's top-left corner.
    fn layout(&self) -> (u32, u32, Vec<Prim>, Vec<(u32, u32)>) {
        let cell_w = self.panels.iter().map(|f| f.w).max().unwrap_or(120);
        let cell_h = self.panels.iter().map(|f| f.h).max().unwrap_or(120);
        let cols = self.cols.min(self.panels.len()).max(1) as u32;
        let rows = self.panels.len().div_ceil(cols as usize).max(1) as u32;
        let w = cols * cell_w;
        let sc = text_scale(cell_w, cell_h);
        // The title wraps as a figure's of the whole width.
        let lines = Figure::new(&self.title).size(w, cell_h).title_lines(sc);
        let top = if lines.is_empty() { 0.0 } else { title_height(lines.len(), f64::from(8 * sc)) } as u32;
        let title = title_labels(&lines, sc, |_| f64::from(w) / 2.0);
        let corners = (0..self.panels.len() as u32).map(|k| ((k % cols) * cell_w, top + (k / cols) * cell_h)).collect();
        (w, top + rows * cell_h, title, corners)
    }

    /// The first inside corner free for the legend in every panel that has one, so that
    /// sibling panels keep their legends in one place.
    fn legend_corner(&self) -> Option<usize> {
        let free: Vec<[bool; 4]> = self.panels.iter().filter_map(Figure::legend_corners).collect();
        (0..4).find(|&c| free.iter().all(|f| f[c]))
    }

    /// Render as an SVG 1.1 document, each panel in a group of its own.
    pub fn to_svg(&self) -> String {
        let (w, h, title, corners) = self.layout();
        let corner = self.legend_corner();
        let scenes: Vec<(Layout, Vec<Prim>)> = self.panels.iter().map(|f| f.scene_preferring(corner)).collect();
        let mut parts = vec![svg::Part { at: (0.0, 0.0), frame: [0.0, 0.0, f64::from(w), f64::from(h)], prims: &title }];
        for ((lay, prims), &(x, y)) in scenes.iter().zip(&corners) {
            parts.push(svg::Part { at: (f64::from(x), f64::from(y)), frame: lay.frame(), prims });
        }
        svg::document(w, h, &parts)
    }

    /// Render as a PNG file (RGB, 8 bits per channel).
    pub fn to_png(&self) -> Vec<u8> {
        let canvas = self.raster();
        png::encode(canvas.w, canvas.h, &canvas.px)
    }

    fn raster(&self) -> raster::Canvas {
        let (w, h, title, corners) = self.layout();
        let mut canvas = raster::Canvas::new(w, h);
        for p in &title {
            canvas.draw(p, [0.0, 0.0, f64::from(w), f64::from(h)]);
        }
        let corner = self.legend_corner();
        for (fig, &(x, y)) in self.panels.iter().zip(&corners) {
            canvas.blit(&fig.raster_preferring(corner), x, y);
        }
        canvas
    }
}

/// An image a report writes as SVG and PNG: one [`Figure`] or [`Panels`] of them.
pub trait Image {
    fn svg(&self) -> String;
    fn png(&self) -> Vec<u8>;
}

impl Image for Figure {
    fn svg(&self) -> String {
        self.to_svg()
    }
    fn png(&self) -> Vec<u8> {
        self.to_png()
    }
}

impl Image for Panels {
    fn svg(&self) -> String {
        self.to_svg()
    }
    fn png(&self) -> Vec<u8> {
        self.to_png()
    }
}

/// Whether data primitive `p` would be hidden, even in part, by an opaque
/// box `bx` (grown by the line half-width or dot radius plus a pixel).
/// Segments are tested exactly, not by sampling.
fn covers(p: &Prim, bx: [f64; 4]) -> bool {
    let grow = |m: f64| [bx[0] - m, bx[1] - m, bx[2] + m, bx[3] + m];
    match p {
        Prim::Path(parts, _, width, _) => {
            let g = grow(width / 2.0 + 1.0);
            parts.iter().any(|part| match part.as_slice() {
                [only] => raster::clip_segment(*only, *only, g).is_some(),
                _ => part
                    .windows(2)
                    .any(|w| raster::clip_segment(w[0], w[1], g).is_some()),
            })
        }
        Prim::Dots(pts, _, r, _, _) => {
            let g = grow(r + 1.0);
            pts.iter()
                .any(|&(x, y)| x >= g[0] && x <= g[2] && y >= g[1] && y <= g[3])
        }
        _ => false,
    }
}

fn pick(p: (f64, f64), axis: usize) -> f64 {
    if axis == 0 { p.0 } else { p.1 }
}

/// Pixel width of `s` in the PNG font (also used as the SVG estimate).
fn text_w(s: &str, scale: u32) -> f64 {
    f64::from(font::text_width(&font::to_ascii(s), scale))
}

/// Primitives for one data series, drawn with `pen` (see [`pen`]).
fn series_prims(lay: &Layout, s: &Series, pen: Pen, prims: &mut Vec<Prim>) {
    let color = s.color;
    let width = |base: f64| (base + pen.widen).max(1.0);
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    match &s.kind {
        Kind::Xy(pts, marker) => {
            if !matches!(marker, Marker::Points | Marker::Cloud) {
                // Split into runs of finite points: NaN/inf break the line.
                let mut parts: Vec<Vec<(f64, f64)>> = Vec::new();
                for run in pts.split(|p| !finite(p)).filter(|r| !r.is_empty()) {
                    let mut part = Vec::with_capacity(run.len());
                    for (i, &p) in run.iter().enumerate() {
                        if *marker == Marker::Steps && i > 0 {
                            part.push(lay.map((p.0, run[i - 1].1)));
                        }
                        part.push(lay.map(p));
                    }
                    parts.push(part);
                }
                let base = if *marker == Marker::LinePoints {
                    1.5
                } else {
                    2.0
                };
                if !parts.is_empty() {
                    prims.push(Prim::Path(parts, color, width(base), pen.dash));
                }
            }
            if matches!(marker, Marker::Points | Marker::LinePoints | Marker::Cloud) {
                let pts: Vec<_> = pts
                    .iter()
                    .filter(|p| finite(p))
                    .map(|&p| lay.map(p))
                    .collect();
                let (r, ring) = if *marker == Marker::Cloud { (CLOUD_R, false) } else { (pen.dot_r, pen.ring) };
                if !pts.is_empty() {
                    prims.push(Prim::Dots(pts, color, r, ring, true));
                }
            }
        }
        Kind::Arrows(arrows) => {
            // Shaft plus two barbs at +-25 degrees, at most 10 px long. Heads
            // go to a solid path of their own if the shafts are dashed (a
            // dashed head could lose its tip).
            let (cos, sin) = (25f64.to_radians().cos(), 25f64.to_radians().sin());
            let (mut parts, mut heads) = (Vec::new(), Vec::new());
            for &(p, q) in arrows {
                let (a, b) = (lay.map(p), lay.map(q));
                parts.push(vec![a, b]);
                let len = (b.0 - a.0).hypot(b.1 - a.1);
                if len > 1.0 {
                    let head = (0.35 * len).min(10.0);
                    let (ux, uy) = ((b.0 - a.0) / len, (b.1 - a.1) / len);
                    let barb = |sg: f64| {
                        let (rx, ry) = (cos * ux - sg * sin * uy, sg * sin * ux + cos * uy);
                        (b.0 - head * rx, b.1 - head * ry)
                    };
                    let head = vec![barb(1.0), b, barb(-1.0)];
                    if pen.dash.is_some() {
                        heads.push(head);
                    } else {
                        parts.push(head);
                    }
                }
            }
            if !parts.is_empty() {
                prims.push(Prim::Path(parts, color, width(ARROW_W), pen.dash));
            }
            if !heads.is_empty() {
                prims.push(Prim::Path(heads, color, width(ARROW_W), None));
            }
        }
    }
}

/// Axis range: a valid fixed range wins; otherwise the data range with 3%
/// padding; a degenerate range is widened around its value; no data -> [0, 1].
fn axis_range(fixed: Option<(f64, f64)>, data: Option<(f64, f64)>) -> (f64, f64) {
    let (lo, hi, pad) = match fixed {
        Some((a, b)) if a.is_finite() && b.is_finite() => (a.min(b), a.max(b), 0.0),
        _ => match data {
            Some((a, b)) => (a, b, 0.03),
            None => return (0.0, 1.0),
        },
    };
    let span = hi - lo;
    if span == 0.0 {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    if !span.is_finite() {
        // Extreme values: fall back to a symmetric range that still maps.
        return (-f64::MAX / 4.0, f64::MAX / 4.0);
    }
    (lo - pad * span, hi + pad * span)
}

/// Nice step (1, 2 or 5 times a power of ten) giving about `target` intervals.
fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let norm = raw / mag;
    let m = [1.0, 2.0, 5.0]
        .into_iter()
        .find(|&m| norm <= m)
        .unwrap_or(10.0);
    m * mag
}

/// Tick values (multiples of `step`) inside `[lo, hi]` with their labels.
fn ticks(lo: f64, hi: f64, step: f64) -> Vec<(f64, String)> {
    let (k0, k1) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
    if !(k0.is_finite() && k1.is_finite() && step > 0.0) || k1 < k0 || k1 - k0 > 100.0 {
        return Vec::new();
    }
    let values: Vec<f64> = (0..=(k1 - k0) as i64).map(|i| (k0 + i as f64) * step).collect();
    // One notation for the whole axis: 20000 beside 1e5 reads as two scales.
    let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scientific = !(1e-3..1e5).contains(&largest);
    if !scientific {
        return values.into_iter().map(|v| (v, fmt_tick(v, step, false))).collect();
    }
    // The same number of digits in every mantissa (9.490e5, 9.495e5, 9.500e5; 9.0e5 ..
    // 1.0e6), as few as all of them allow (2e4 .. 1e5): the largest value's digits for the
    // step, trimmed alike.
    let mut digits = (largest.log10().floor() as i32 - step.log10().floor() as i32).clamp(0, 10) as usize;
    let label = |v: f64, digits: usize| if v.abs() < step * 1e-6 { "0".to_string() } else { format!("{v:.digits$e}") };
    let trailing_zero = |l: &String| l.split_once('e').is_none_or(|(m, _)| m.ends_with('0'));
    while digits > 0 && values.iter().map(|&v| label(v, digits)).all(|l| trailing_zero(&l)) {
        digits -= 1;
    }
    values.into_iter().map(|v| (v, label(v, digits))).collect()
}

/// Label for tick value `v` on a grid of spacing `step`: plain decimals with just enough
/// digits, or `scientific` notation (for axes of very large or small values).
fn fmt_tick(v: f64, step: f64, scientific: bool) -> String {
    if v.abs() < step * 1e-6 {
        return "0".to_string();
    }
    let step_exp = step.log10().floor() as i32;
    let v_exp = v.abs().log10().floor() as i32;
    if scientific {
        // Untrimmed: `ticks` trims the mantissas of an axis alike.
        let digits = (v_exp - step_exp).clamp(0, 10) as usize;
        format!("{v:.digits$e}")
    } else {
        let digits = (-step_exp).clamp(0, 10) as usize;
        format!("{v:.digits$}")
    }
}

/// Ticks for `range` over `len_px` pixels, as dense as possible such that
/// neighbouring labels are at least `need(label)` pixels apart.
fn fit_ticks(range: (f64, f64), len_px: f64, need: impl Fn(&str) -> f64) -> Vec<(f64, String)> {
    let span = range.1 - range.0;
    let mut target = ((len_px / 40.0) as usize).clamp(2, 12);
    loop {
        let step = nice_step(span, target);
        let ticks = ticks(range.0, range.1, step);
        let step_px = step / span * len_px;
        if target <= 2 || ticks.iter().all(|(_, s)| need(s) <= step_px) {
            return ticks;
        }
        target -= 1;
    }
}
