//! Drawing a band of columns of the level view: each column is a vertical plane, marched through
//! the 1 m cells front to back. Flat cells are drawn row by row at once; other cells are sampled
//! along the ray on the 0.25 m height field, and each sample fills the rows between it and the
//! last one drawn. The terrain of a column between two drawn ones is blended from theirs. Bands
//! of columns are independent, so threads can draw them side by side.

use std::ops::Range;

use wide::{f32x4, i32x4};

use super::appearance::{Appearance, Facing, NodeShade, fog_weights, lerp3, scale3, shade, shade_fixed, to_rgb8};
use super::objects::PieceInView;
use super::surveyed::RockInView;
use super::view::{LevelView, Window, ceil_row};
use super::{Hit, RenderOptions, Surface, truncated_index};
use crate::terrain::{MAX_TERRAIN_HEIGHT_M, Terrain};
use crate::world::{Sample, World, inside_world};

/// Rays stop after this horizontal depth, metres (the world's diagonal).
const MAX_DEPTH_M: f64 = 290.0;
/// Along a ray, the terrain is sampled every this fraction of the depth...
const MARCH_STEP_FRACTION: f64 = 0.04;
/// ...and at least this often, metres.
const MARCH_STEP_MIN_M: f64 = 0.03;
/// Two neighbouring pixels whose forward depths differ by more than this fraction of the nearer
/// lie on two sides of an outline: the pixel between them takes the nearer one's colour, not their
/// mean.
const BLEND_DEPTH_FRACTION: f32 = 0.1;
/// Colour of the calibration grid lines.
const GRID_RGB: [f32; 3] = [38.0, 36.0, 34.0];
/// Half width of a grid line, metres.
const GRID_HALF_WIDTH_M: f64 = 0.012;

/// What every pixel of one level row shares: the sky's colour and, below the horizon, what every
/// floor pixel shares: its forward depth, its colour before texture (fog included), how much of a
/// surface shows through the fog, and the fog's own colour.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LevelRow {
    sky: [u8; 3],
    depth: f64,
    footprint_m: f32,
    rgb: [f32; 3],
    visible: f32,
    haze: [f32; 3],
}

/// The rows of a frame seen from `view`, one per level row (the floor's values only below the
/// horizon).
pub(super) fn level_rows(view: &LevelView, appearance: &Appearance, rows: &mut [LevelRow]) {
    let look = &appearance.look;
    for (v, row) in rows.iter_mut().enumerate() {
        let sky = to_rgb8(lerp3(look.sky_top_rgb, look.sky_horizon_rgb, (v as f64 / view.cy_px).min(1.0) as f32));
        *row = if v as f64 > view.cy_px {
            let depth = view.focal_px * view.camera.z.max(1e-3) / (v as f64 - view.cy_px);
            let (visible, haze) = fog_weights(depth);
            let rgb = scale3(appearance.floor_rgb(depth), visible);
            LevelRow { sky, depth, footprint_m: view.footprint_m(depth), rgb, visible, haze }
        } else {
            LevelRow { sky, ..LevelRow::default() }
        };
    }
}

/// What every band of one frame shares while it is drawn.
pub(super) struct Frame<'a> {
    pub(super) world: &'a World,
    pub(super) samples: &'a [Sample],
    pub(super) pieces: Vec<PieceInView<'a>>,
    pub(super) rocks: Vec<RockInView<'a>>,
    pub(super) view: LevelView,
    pub(super) window: Window,
    pub(super) appearance: &'a Appearance,
    pub(super) rows: &'a [LevelRow],
    pub(super) options: RenderOptions,
    /// Whether every other column's terrain is blended from its neighbours' ([`Painter::draw`]).
    pub(super) blend_columns: bool,
    pub(super) level_height: usize,
}

/// A band of level columns and the pixels it draws into (column by column).
pub(super) struct Band<'a> {
    pub(super) columns: Range<usize>,
    pub(super) rgb: &'a mut [[u8; 3]],
    pub(super) depth: &'a mut [f32],
    /// Empty unless the frame records hits.
    pub(super) hits: &'a mut [Hit],
}

/// Draws one band of one frame.
pub(super) struct Painter<'f, 'b> {
    pub(super) frame: &'f Frame<'f>,
    pub(super) band: Band<'b>,
}

/// A point of the terrain along a column's ray, as drawn: its row, the values the pixels between
/// two points interpolate in fixed point, and those they interpolate exactly (see the `EXACT_`
/// indices).
#[derive(Debug, Clone, Copy)]
struct RayPoint {
    row: f64,
    fixed: FixedLanes,
    exact: [f32; EXACT_LANES],
}

/// The last point marched along a column's ray: where it is, and how it is drawn once it has
/// been needed (a point that fills no row, hidden behind nearer terrain or less than a row below
/// the last one drawn, is shaded only when the next point starts its span from it).
#[derive(Debug, Clone, Copy)]
struct Marched {
    depth: f64,
    z: f64,
    point: Option<RayPoint>,
}

/// The values of a [`RayPoint`] the pixels between two points interpolate in fixed point (1/256
/// units), four to a vector so that a row's step is three vector additions: the texel
/// coordinates of the floor's and the rock's textures (floor u, v, rock u, v); the colour before
/// texture, fog included, with the rock weight in the fourth lane; the fog's colour (its fourth
/// lane unused).
#[derive(Debug, Clone, Copy, Default)]
struct FixedLanes {
    texture: i32x4,
    colour: i32x4,
    haze: i32x4,
}

/// The lane of [`FixedLanes::colour`] that holds the rock weight.
const ROCK_LANE: usize = 3;

impl FixedLanes {
    /// `f` applied to the matching vectors of `self` and `other`.
    fn zip(self, other: FixedLanes, f: impl Fn(i32x4, i32x4) -> i32x4) -> FixedLanes {
        FixedLanes {
            texture: f(self.texture, other.texture),
            colour: f(self.colour, other.colour),
            haze: f(self.haze, other.haze),
        }
    }

    /// `f` applied to each vector.
    fn map(self, f: impl Fn(i32x4) -> i32x4) -> FixedLanes {
        FixedLanes { texture: f(self.texture), colour: f(self.colour), haze: f(self.haze) }
    }

    /// The rock weight, unclamped.
    fn rock(&self) -> i32 {
        self.colour.as_array()[ROCK_LANE]
    }
}

/// Four values in units (texels, colour levels, weights) in fixed point, truncated.
fn fixed_lanes(values: [f32; 4]) -> i32x4 {
    (f32x4::new(values) * f32x4::splat(FIXED_ONE)).fast_trunc_int()
}

/// Exact values of a [`RayPoint`]: forward depth, height and sunlight.
const EXACT_LANES: usize = 3;
const EXACT_DEPTH: usize = 0;
const EXACT_HEIGHT: usize = 1;
const EXACT_SUN: usize = 2;
/// One in the fixed-point values.
const FIXED_ONE: f32 = 256.0;

/// Which detail textures the pixels of a [`Span`] show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SpanTexture {
    /// The floor's alone.
    Floor,
    /// The rock's alone.
    Rock,
    /// Both, weighted by the rock weight of each pixel.
    Blend,
}

/// The values of the pixels of a span between two [`RayPoint`]s at one row, and their change from
/// one row to the next.
#[derive(Debug, Clone, Copy)]
struct Span {
    fixed: FixedLanes,
    fixed_step: FixedLanes,
    exact: [f32; EXACT_LANES],
    exact_step: [f32; EXACT_LANES],
}

impl Span {
    /// The span from `from` to `point`, at row `first`. The pixel at `first` lies `start` of the
    /// way from `from` to `point`, each row below one step back towards `from` (all within the
    /// two, as `first` is at or below `point.row` and the rows end above `from.row`). Two points
    /// less than a row apart fill with `point`'s values (a row's step would take them far beyond
    /// both).
    fn between(from: &RayPoint, point: &RayPoint, first: usize) -> Self {
        let rows = from.row - point.row;
        if rows < 1.0 {
            let (fixed_step, exact_step) = (FixedLanes::default(), [0.0; EXACT_LANES]);
            return Span { fixed: point.fixed, fixed_step, exact: point.exact, exact_step };
        }
        let (start, per_row) = ((from.row - first as f64) / rows, -1.0 / rows);
        let delta = point.fixed.zip(from.fixed, |to, from| to - from);
        let part = |of: f64| delta.map(|d| (d.round_float() * f32x4::splat(of as f32)).fast_trunc_int());
        let (mut exact, mut exact_step) = (from.exact, [0f32; EXACT_LANES]);
        for k in 0..EXACT_LANES {
            let delta = point.exact[k] - from.exact[k];
            exact[k] += delta * start as f32;
            exact_step[k] = delta * per_row as f32;
        }
        Span {
            fixed: from.fixed.zip(part(start), |from, part| from + part),
            fixed_step: part(per_row),
            exact,
            exact_step,
        }
    }

    /// The weight of the rock's colour, 0..=256.
    fn rock(&self) -> i32 {
        self.fixed.rock().clamp(0, FIXED_ONE as i32)
    }

    /// Which textures the span's pixels show: the rock weight is the same along a span whose ends
    /// agree, so a span all floor or all rock looks up one texture a pixel.
    fn texture(&self) -> SpanTexture {
        match (self.fixed.rock(), self.fixed_step.rock()) {
            (0, 0) => SpanTexture::Floor,
            (256, 0) => SpanTexture::Rock,
            _ => SpanTexture::Blend,
        }
    }

    /// The detail texture of the pixel, when it shows `texture`.
    fn texel(&self, appearance: &Appearance, texture: SpanTexture) -> u32 {
        let [floor_u, floor_v, rock_u, rock_v] = self.fixed.texture.to_array();
        let floor_texel = || appearance.floor_texel_fixed(floor_u, floor_v);
        let rock_texel = || appearance.rock_texel_fixed(rock_u, rock_v);
        match texture {
            SpanTexture::Floor => floor_texel(),
            SpanTexture::Rock => rock_texel(),
            SpanTexture::Blend => match self.rock() {
                0 => floor_texel(),
                256 => rock_texel(),
                rock => {
                    let floor = floor_texel() as i32;
                    (floor + (((rock_texel() as i32 - floor) * rock) >> 8)) as u32
                }
            },
        }
    }

    /// The colour of the pixel with the detail texture `texel`.
    fn colour(&self, texel: u32) -> [u8; 3] {
        shade_fixed(self.fixed.colour, texel, self.fixed.haze)
    }

    /// Fills `rgb` and `depth`, one pixel a row, with the span's colours showing `texture` (the
    /// same texture for every call of the pixel loop, so that each kind gets its own loop).
    #[inline(always)]
    fn fill(mut self, appearance: &Appearance, texture: SpanTexture, rgb: &mut [[u8; 3]], depth: &mut [f32]) {
        for (rgb, depth) in rgb.iter_mut().zip(depth) {
            *rgb = self.colour(self.texel(appearance, texture));
            *depth = self.exact[EXACT_DEPTH];
            self.advance_colour();
        }
    }

    /// What the pixel's ray hit.
    fn hit(&self) -> Hit {
        let rock = self.rock();
        Hit {
            surface: if rock < 128 { Surface::Floor } else { Surface::Rock },
            depth_m: self.exact[EXACT_DEPTH],
            height_m: self.exact[EXACT_HEIGHT],
            sun: self.exact[EXACT_SUN],
            rock: rock as f32 / FIXED_ONE,
        }
    }

    /// Moves the lanes a pixel's colour and depth need on to the next row.
    fn advance_colour(&mut self) {
        self.fixed = self.fixed.zip(self.fixed_step, |value, step| value + step);
        self.exact[EXACT_DEPTH] += self.exact_step[EXACT_DEPTH];
    }

    /// Moves every lane on to the next row.
    fn advance(&mut self) {
        self.advance_colour();
        for lane in [EXACT_HEIGHT, EXACT_SUN] {
            self.exact[lane] += self.exact_step[lane];
        }
    }
}

impl Painter<'_, '_> {
    /// Draws the band: terrain and sky, then the rocks and the samples over them. When the
    /// frame blends columns, the terrain of every other column of the band is drawn and that of
    /// each column between two drawn ones is blended from theirs.
    pub(super) fn draw(&mut self) {
        let frame = self.frame;
        let columns = self.band.columns.clone();
        let blended = |u: &usize| frame.blend_columns && is_between(&columns, *u);
        for u in columns.clone().filter(|u| !blended(u)) {
            self.draw_column(frame.world.terrain(), u);
        }
        for u in columns.clone().filter(blended) {
            self.blend_neighbours(u);
        }
        for piece in &frame.pieces {
            self.draw_piece(piece);
        }
        for rock in &frame.rocks {
            self.draw_surveyed_rock(rock);
        }
        for sample in frame.samples {
            self.draw_sample(&sample.centre(), sample.radius_m);
        }
    }

    /// Index of level pixel (u, v) in the band's buffers.
    pub(super) fn index(&self, u: usize, v: usize) -> usize {
        (u - self.band.columns.start) * self.frame.level_height + v
    }

    /// Forward depth of what the pixel at `index` shows so far.
    pub(super) fn depth_at(&self, index: usize) -> f32 {
        self.band.depth[index]
    }

    /// Draws a pixel.
    pub(super) fn put(&mut self, index: usize, rgb: [u8; 3], hit: Hit) {
        self.band.rgb[index] = rgb;
        self.band.depth[index] = hit.depth_m;
        if let Some(slot) = self.band.hits.get_mut(index) {
            *slot = hit;
        }
    }

    /// Fills level column `u` from columns `u - 1` and `u + 1`, already drawn: each pixel with the
    /// mean of theirs where their forward depths agree within [`BLEND_DEPTH_FRACTION`], else (an
    /// outline, or the sky in both) with the nearer one's colour and hit. There the depth the
    /// boulders and samples are drawn against is the farther one's, so that one between the two
    /// shows rather than hides behind an edge that may lie half a column off.
    fn blend_neighbours(&mut self, u: usize) {
        let Window { v0, v1, .. } = self.frame.window;
        let (left, here, right) = (self.index(u - 1, v0), self.index(u, v0), self.index(u + 1, v0));
        for row in 0..v1 - v0 {
            let (depth_left, depth_right) = (self.band.depth[left + row], self.band.depth[right + row]);
            let nearer = if depth_left <= depth_right { left } else { right };
            let (near_m, far_m) = (depth_left.min(depth_right), depth_left.max(depth_right));
            let (rgb, hit_depth_m, drawn_over_m) = if far_m - near_m <= BLEND_DEPTH_FRACTION * near_m {
                let (rgb_left, rgb_right) = (self.band.rgb[left + row], self.band.rgb[right + row]);
                let mean_m = near_m.midpoint(far_m);
                (std::array::from_fn(|c| rgb_left[c].midpoint(rgb_right[c])), mean_m, mean_m)
            } else {
                (self.band.rgb[nearer + row], near_m, far_m)
            };
            self.band.rgb[here + row] = rgb;
            self.band.depth[here + row] = drawn_over_m;
            if let Some(hits) = self.band.hits.get_mut(left + row..=right + row) {
                hits[here - left] = Hit { depth_m: hit_depth_m, ..hits[nearer - left] };
            }
        }
    }

    /// Draws the terrain and the sky of level column `u`.
    fn draw_column(&mut self, terrain: &Terrain, u: usize) {
        let view = &self.frame.view;
        let [dx, dy] = view.column_direction(u);
        let (mut ix, mut iy) = (view.camera.x.floor() as i64, view.camera.y.floor() as i64);
        let (step_x, step_y) = (if dx >= 0.0 { 1 } else { -1 }, if dy >= 0.0 { 1 } else { -1 });
        let next_boundary = |p: f64, i: i64, step: i64| if step > 0 { (i + 1) as f64 - p } else { p - i as f64 };
        let (mut t_x, mut t_y) = (
            if dx == 0.0 { f64::INFINITY } else { next_boundary(view.camera.x, ix, step_x) / dx.abs() },
            if dy == 0.0 { f64::INFINITY } else { next_boundary(view.camera.y, iy, step_y) / dy.abs() },
        );
        let (delta_x, delta_y) = (1.0 / dx.abs(), 1.0 / dy.abs());
        let mut t_in = 0.0;
        let Window { v0: top, v1: mut bottom, .. } = self.frame.window;
        let mut last: Option<Marched> = None;
        let mut floor_until: Option<f64> = None;
        while bottom > top && t_in < MAX_DEPTH_M && view.row(t_in, MAX_TERRAIN_HEIGHT_M as f64) < bottom as f64 {
            let t_out = t_x.min(t_y);
            let highest = terrain.cell_max_height(ix, iy) as f64;
            if highest <= 0.0 {
                let plain = self.frame.appearance.is_plain_floor(ix, iy);
                bottom = self.draw_floor(u, [dx, dy], t_out, bottom, plain);
                (last, floor_until) = (None, Some(t_out));
            } else if hidden(view, highest, t_in, t_out, bottom) {
                (last, floor_until) = (None, None);
            } else {
                if let Some(t) = floor_until.take() {
                    last = Some(Marched { depth: t, z: 0.0, point: None });
                }
                let mut t = t_in;
                while t < t_out {
                    t = (t + (t * MARCH_STEP_FRACTION).max(MARCH_STEP_MIN_M)).min(t_out);
                    let (x, y) = (view.camera.x + t * dx, view.camera.y + t * dy);
                    let z = terrain.height_at(x, y) as f64;
                    let mut marched = Marched { depth: t, z, point: None };
                    let row = view.row(t, z);
                    if row < bottom as f64 && ceil_row(row).max(top) < bottom {
                        let from = last.map(|m| m.point.unwrap_or_else(|| self.ray_point([dx, dy], m.depth, m.z)));
                        let point = self.ray_point([dx, dy], t, z);
                        bottom = self.fill_span(u, bottom, from.as_ref(), &point);
                        marched.point = Some(point);
                    }
                    last = Some(marched);
                }
            }
            if t_x < t_y {
                ix += step_x;
                t_x += delta_x;
            } else {
                iy += step_y;
                t_y += delta_y;
            }
            t_in = t_out;
        }
        self.fill_sky(u, top, bottom);
    }

    /// Fills rows `top..bottom` of level column `u` with the sky.
    fn fill_sky(&mut self, u: usize, top: usize, bottom: usize) {
        let pixels = self.index(u, top)..self.index(u, bottom);
        let rows = &self.frame.rows[top..bottom];
        for (rgb, row) in self.band.rgb[pixels.clone()].iter_mut().zip(rows) {
            *rgb = row.sky;
        }
        self.band.depth[pixels.clone()].fill(f32::INFINITY);
        if let Some(hits) = self.band.hits.get_mut(pixels) {
            hits.fill(Hit::SKY);
        }
    }

    /// The terrain point at forward depth `depth` along a column's ray (direction `dir`), at
    /// height `z`.
    fn ray_point(&self, dir: [f64; 2], depth: f64, z: f64) -> RayPoint {
        let (view, appearance) = (&self.frame.view, self.frame.appearance);
        let (x, y) = (view.camera.x + depth * dir[0], view.camera.y + depth * dir[1]);
        let shade = if inside_world(x, y) {
            appearance.shade_at(x, y)
        } else {
            NodeShade { rock: 1.0, floor: 1.0, sun: 0.5, wall_m: 0.0, facing: Facing::AlongX }
        };
        let (visible, haze) = fog_weights(depth);
        let rgb = scale3(appearance.terrain_rgb(&shade, depth, view.footprint_m(depth)), visible);
        let (floor_u, floor_v) = appearance.floor_texture_coordinates(x as f32, y as f32);
        let (a, b) = shade.facing.texture_coordinates(x as f32, y as f32, z as f32);
        let (rock_u, rock_v) = appearance.rock_texture_coordinates(a, b);
        let fixed = FixedLanes {
            texture: fixed_lanes([floor_u, floor_v, rock_u, rock_v]),
            colour: fixed_lanes([rgb[0], rgb[1], rgb[2], shade.rock]),
            haze: fixed_lanes([haze[0], haze[1], haze[2], 0.0]),
        };
        RayPoint { row: view.row(depth, z), fixed, exact: [depth as f32, z as f32, shade.sun] }
    }

    /// Fills the rows from `point` down to `bottom` with the terrain between `last` and `point`;
    /// returns the new bottom. The pixels of a column are one slice of the band's buffers, filled
    /// in one pass; what each ray hit, only when the frame records it, in a second.
    fn fill_span(&mut self, u: usize, bottom: usize, last: Option<&RayPoint>, point: &RayPoint) -> usize {
        let appearance = self.frame.appearance;
        let first = ceil_row(point.row).max(self.frame.window.v0);
        if first >= bottom {
            return bottom;
        }
        let span = Span::between(last.unwrap_or(point), point, first);
        let pixels = self.index(u, first)..self.index(u, bottom);
        let rgb = &mut self.band.rgb[pixels.clone()];
        let depth = &mut self.band.depth[pixels.clone()];
        match span.texture() {
            SpanTexture::Floor => span.fill(appearance, SpanTexture::Floor, rgb, depth),
            SpanTexture::Rock => span.fill(appearance, SpanTexture::Rock, rgb, depth),
            SpanTexture::Blend => span.fill(appearance, SpanTexture::Blend, rgb, depth),
        }
        if let Some(hits) = self.band.hits.get_mut(pixels) {
            let mut lanes = span;
            for hit in hits {
                *hit = lanes.hit();
                lanes.advance();
            }
        }
        first
    }

    /// Draws the floor rows of one flat cell (forward depths up to `t_out`): all of the floor's
    /// colour when `plain`, else shaded node by node; returns the new bottom.
    fn draw_floor(&mut self, u: usize, dir: [f64; 2], t_out: f64, bottom: usize, plain: bool) -> usize {
        let (view, appearance) = (&self.frame.view, self.frame.appearance);
        let first = truncated_index(view.row(t_out, 0.0).max(0.0)).saturating_add(1);
        let sun = appearance.look.sun.z as f32;
        for v in first..bottom {
            let LevelRow { depth, footprint_m, rgb, visible, haze, .. } = self.frame.rows[v];
            let (x, y) = (view.camera.x + depth * dir[0], view.camera.y + depth * dir[1]);
            let (mut pixel, rock) = if plain {
                (shade(rgb, appearance.floor_factor(x, y, footprint_m), haze), 0.0)
            } else {
                appearance.painted_floor(x, y, rgb, (visible, haze), footprint_m)
            };
            if self.frame.options.grid {
                let rgb = pixel.map(f32::from);
                pixel = to_rgb8(lerp3(rgb, GRID_RGB, grid_coverage(x, y, depth, view)));
            }
            let surface = if rock < 0.5 { Surface::Floor } else { Surface::Rock };
            let index = self.index(u, v);
            self.put(index, pixel, Hit { surface, depth_m: depth as f32, height_m: 0.0, sun, rock });
        }
        first.min(bottom)
    }
}

/// True if column `u` of a band of `columns` lies between two other columns of it, every other
/// one from the band's first (the band's last is never between).
fn is_between(columns: &Range<usize>, u: usize) -> bool {
    (u - columns.start) % 2 == 1 && u + 1 < columns.end
}

/// True if nothing of a cell whose terrain reaches `highest` metres, crossed between forward depths
/// `t_in` and `t_out`, can show above row `bottom`.
fn hidden(view: &LevelView, highest: f64, t_in: f64, t_out: f64, bottom: usize) -> bool {
    let nearest_row =
        if highest > view.camera.z { view.row(t_in.max(1e-6), highest) } else { view.row(t_out, highest) };
    nearest_row >= bottom as f64
}

/// How much of the floor pixel at (x, y), `depth` ahead, a grid line covers.
fn grid_coverage(x: f64, y: f64, depth: f64, view: &LevelView) -> f32 {
    let footprint = depth * depth / (view.focal_px * view.camera.z.max(0.05)) + depth / view.focal_px;
    let coverage = |p: f64| {
        let distance = ((p - 0.5) - (p - 0.5).round()).abs();
        ((GRID_HALF_WIDTH_M + footprint * 0.5 - distance) / footprint).clamp(0.0, 1.0)
    };
    coverage(x).max(coverage(y)) as f32
}
