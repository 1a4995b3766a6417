//! Drawing surveyed rocks: each a grid of columns of rock, solid from a bottom to a top height over
//! its cell. A level column's ray crosses the grid cell by cell, front to back. In the vertical
//! plane of the column a cell's rock is a rectangle of depth and height, so it covers the rows
//! between its corners, and the ray of each of those rows enters it through the near side, the top
//! or the underside.

use std::ops::Range;

use nalgebra::{Point3, Vector3};

use super::appearance::{Appearance, Facing, fog_weights, scale3, shade};
use super::columns::Painter;
use super::view::{LevelView, NEAR_M, Window, whole_pixels};
use super::{Hit, Surface};
use crate::rock_survey::SurveyedRock;

/// Rocks farther than this are not drawn, metres.
const MAX_ROCK_DEPTH_M: f64 = 290.0;

/// How each cell of a surveyed rock faces the sun, baked once per world: the cell's top surface
/// (its slope from the neighbouring tops, the ground where there is no rock) lights its top and
/// sides; the underside is in shade.
pub(super) struct RockShading {
    /// Sunlight 0..1 per cell, row by row like the rock's columns.
    sun: Vec<f32>,
}

impl RockShading {
    /// The shading of `rock` under the sun of `appearance`.
    pub(super) fn new(rock: &SurveyedRock, appearance: &Appearance) -> Self {
        let top = |c: i64, r: i64| rock.column(c, r).map_or(0.0, |column| column.top_m as f64);
        let sun = (0..rock.rows * rock.cols)
            .map(|i| {
                let (c, r) = ((i % rock.cols) as i64, (i / rock.cols) as i64);
                let slope_x = (top(c + 1, r) - top(c - 1, r)) / (2.0 * rock.cell_m);
                let slope_y = (top(c, r + 1) - top(c, r - 1)) / (2.0 * rock.cell_m);
                appearance.sunlight(&Vector3::new(-slope_x, -slope_y, 1.0).normalize())
            })
            .collect();
        RockShading { sun }
    }
}

/// A surveyed rock that can show in a frame, and the level columns it can cover.
pub(super) struct RockInView<'a> {
    rock: &'a SurveyedRock,
    shading: &'a RockShading,
    columns: Range<usize>,
}

/// The surveyed rocks of `rocks` (with their shading) that can show in `window` of `view`: a rock
/// wholly behind the camera, beside the window or too far off is left out by its box.
pub(super) fn rocks_in_view<'a>(
    rocks: &'a [SurveyedRock],
    shadings: &'a [RockShading],
    view: &LevelView,
    window: Window,
) -> Vec<RockInView<'a>> {
    let mut in_view = Vec::new();
    for (rock, shading) in rocks.iter().zip(shadings) {
        let [[x0, y0], [x1, y1]] = crate::obstacle::Obstacle::bounds_m(rock);
        let corners: Vec<Option<(f64, f64, f64)>> = (0..8)
            .map(|k| {
                let pick = |bit: usize, lo: f64, hi: f64| if k >> bit & 1 == 0 { lo } else { hi };
                view.project(&Point3::new(pick(0, x0, x1), pick(1, y0, y1), pick(2, 0.0, rock.highest_m())))
            })
            .collect();
        if corners.iter().all(Option::is_none) {
            continue;
        }
        let mut columns = window.u0..window.u1;
        if corners.iter().all(Option::is_some) {
            let (lo_u, hi_u) =
                corners.iter().flatten().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.0), hi.max(c.0)));
            let nearest = corners.iter().flatten().map(|c| c.2).fold(f64::MAX, f64::min);
            columns = whole_pixels(lo_u, hi_u, columns);
            if columns.is_empty() || nearest > MAX_ROCK_DEPTH_M {
                continue;
            }
        }
        in_view.push(RockInView { rock, shading, columns });
    }
    in_view
}

/// Which face of a cell's column a ray enters through.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Entry {
    /// The near side, across a cell boundary along x or y.
    Side(Facing),
    /// The top.
    Top,
    /// The underside.
    Underside,
}

/// The forward depth where the ray of a row rising `rise` per metre from a camera at height
/// `camera_z` enters rock spanning `bottom_m..top_m` over the depths `t_in..t_out`, and through
/// which face; none if it passes above or below.
fn entry(
    camera_z: f64,
    rise: f64,
    [bottom_m, top_m]: [f64; 2],
    [t_in, t_out]: [f64; 2],
    side: Facing,
) -> Option<(f64, Entry)> {
    let z_in = camera_z + rise * t_in;
    let (t, face) = if z_in > top_m {
        (rise < 0.0).then(|| ((top_m - camera_z) / rise, Entry::Top))?
    } else if z_in < bottom_m {
        (rise > 0.0).then(|| ((bottom_m - camera_z) / rise, Entry::Underside))?
    } else {
        (t_in, Entry::Side(side))
    };
    (t <= t_out).then_some((t, face))
}

impl Painter<'_, '_> {
    /// Draws a surveyed rock in the band's columns, where it is the nearest surface.
    pub(super) fn draw_surveyed_rock(&mut self, rock: &RockInView) {
        let columns = rock.columns.start.max(self.band.columns.start)..rock.columns.end.min(self.band.columns.end);
        let mut covered = RowMask::new(self.frame.level_height);
        for u in columns {
            covered.clear();
            self.draw_rock_column(rock, u, &mut covered);
        }
    }

    /// Draws the cells of `rock` that the ray of level column `u` crosses, front to back;
    /// `covered` marks the rows a nearer cell of the rock already covers.
    fn draw_rock_column(&mut self, in_view: &RockInView, u: usize, covered: &mut RowMask) {
        let (view, rock) = (&self.frame.view, in_view.rock);
        let [dx, dy] = view.column_direction(u);
        let [gx, gy] =
            [(view.camera.x - rock.origin_m[0]) / rock.cell_m, (view.camera.y - rock.origin_m[1]) / rock.cell_m];
        let [sx, sy] = [dx / rock.cell_m, dy / rock.cell_m];
        let Some([t_start, t_end]) = grid_crossing([gx, gy], [sx, sy], [rock.cols as f64, rock.rows as f64]) else {
            return;
        };
        let t_start = t_start.max(NEAR_M);
        if t_start >= t_end.min(MAX_ROCK_DEPTH_M) {
            return;
        }
        let cell_of = |p: f64, step: f64, last: usize| {
            let index = (p + step * (t_start + 1e-9)).floor() as i64;
            index.clamp(0, last as i64 - 1)
        };
        let (mut c, mut r) = (cell_of(gx, sx, rock.cols), cell_of(gy, sy, rock.rows));
        let (step_c, step_r) = (if sx >= 0.0 { 1 } else { -1 }, if sy >= 0.0 { 1 } else { -1 });
        let boundary = |g: f64, s: f64, i: i64, step: i64| {
            if s == 0.0 { f64::INFINITY } else { ((i + step.max(0)) as f64 - g) / s }
        };
        let (mut t_c, mut t_r) = (boundary(gx, sx, c, step_c), boundary(gy, sy, r, step_r));
        let (delta_c, delta_r) = (1.0 / sx.abs(), 1.0 / sy.abs());
        let (mut t_in, mut side) =
            (t_start, if t_c - delta_c > t_r - delta_r { Facing::AlongX } else { Facing::AlongY });
        while t_in < t_end && (0..rock.cols as i64).contains(&c) && (0..rock.rows as i64).contains(&r) {
            let t_out = t_c.min(t_r).min(t_end);
            if let Some(column) = rock.column(c, r) {
                let sun = in_view.shading.sun[r as usize * rock.cols + c as usize];
                let span = [column.bottom_m as f64, column.top_m as f64];
                self.draw_rock_cell(u, [dx, dy], span, [t_in, t_out], (side, sun), covered);
            }
            if t_c < t_r {
                (c, t_in, side) = (c + step_c, t_c, Facing::AlongX);
                t_c += delta_c;
            } else {
                (r, t_in, side) = (r + step_r, t_r, Facing::AlongY);
                t_r += delta_r;
            }
        }
    }

    /// Draws the rock spanning heights `span` over the depths `depths` of level column `u`
    /// (horizontal ray direction `dir`), entered across a boundary facing `side` and lit by `sun`,
    /// in the rows no nearer cell of the rock `covered`.
    fn draw_rock_cell(
        &mut self,
        u: usize,
        dir: [f64; 2],
        span: [f64; 2],
        depths: [f64; 2],
        (side, sun): (Facing, f32),
        covered: &mut RowMask,
    ) {
        let (view, appearance) = (&self.frame.view, self.frame.appearance);
        let Window { v0, v1, .. } = self.frame.window;
        let corners = [[0, 1], [1, 1], [0, 0], [1, 0]].map(|[d, h]| view.row(depths[d], span[h]));
        let (first, last) = corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let rows = whole_pixels(first, last, v0..v1);
        let mut next = rows.start;
        while let Some(v) = covered.next_clear(next, rows.end) {
            next = v + 1;
            let rise = view.row_rise(v);
            let Some((t, face)) = entry(view.camera.z, rise, span, depths, side) else { continue };
            covered.set(v);
            let index = self.index(u, v);
            if t as f32 >= self.depth_at(index) {
                continue;
            }
            let point = (view.camera + Vector3::new(dir[0], dir[1], rise) * t).map(|c| c as f32);
            let (facing, sun) = match face {
                Entry::Side(facing) => (facing, sun),
                Entry::Top => (Facing::Up, sun),
                Entry::Underside => (Facing::Up, 0.0),
            };
            let (visible, haze) = fog_weights(t);
            let (a, b) = facing.texture_coordinates(point.x, point.y, point.z);
            let pixel = shade(scale3(appearance.boulder_rgb(sun), visible), appearance.rock_texel(a, b), haze);
            let hit = Hit { surface: Surface::Boulder, depth_m: t as f32, height_m: point.z, sun, rock: 1.0 };
            self.put(index, pixel, hit);
        }
    }
}

/// A set of the rows of a level column, to skip runs of them at once.
pub(super) struct RowMask {
    words: Vec<u64>,
}

impl RowMask {
    fn new(rows: usize) -> Self {
        RowMask { words: vec![0; rows.div_ceil(64)] }
    }

    fn clear(&mut self) {
        self.words.fill(0);
    }

    fn set(&mut self, row: usize) {
        self.words[row / 64] |= 1 << (row % 64);
    }

    /// The first row in `from..end` not in the set.
    fn next_clear(&self, from: usize, end: usize) -> Option<usize> {
        let mut row = from;
        while row < end {
            let free = !self.words[row / 64] >> (row % 64);
            if free == 0 {
                row = (row / 64 + 1) * 64;
                continue;
            }
            row += free.trailing_zeros() as usize;
            return (row < end).then_some(row);
        }
        None
    }
}

/// The parameters `t` where the ray `origin + t * step` is inside the rectangle `0..size` (grid
/// units), if it ever is ahead of the camera.
fn grid_crossing(origin: [f64; 2], step: [f64; 2], size: [f64; 2]) -> Option<[f64; 2]> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for axis in 0..2 {
        if step[axis] == 0.0 {
            if !(0.0..size[axis]).contains(&origin[axis]) {
                return None;
            }
            continue;
        }
        let (a, b) = ((0.0 - origin[axis]) / step[axis], (size[axis] - origin[axis]) / step[axis]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 < t1).then_some([t0, t1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_mask_finds_the_next_row_not_yet_covered() {
        let mut mask = RowMask::new(200);
        (3..70).chain([71, 130]).for_each(|row| mask.set(row));
        assert_eq!(mask.next_clear(0, 200), Some(0));
        assert_eq!(mask.next_clear(3, 200), Some(70));
        assert_eq!(mask.next_clear(71, 200), Some(72));
        assert_eq!(mask.next_clear(130, 131), None);
        assert_eq!(mask.next_clear(40, 60), None);
        mask.clear();
        assert_eq!(mask.next_clear(199, 200), Some(199));
    }

    #[test]
    fn a_ray_crosses_the_grid_between_its_edges() {
        assert_eq!(grid_crossing([-2.0, 1.0], [1.0, 0.0], [4.0, 3.0]), Some([2.0, 6.0]));
        assert_eq!(grid_crossing([1.0, 1.0], [1.0, 0.0], [4.0, 3.0]), Some([0.0, 3.0]), "from inside");
        assert_eq!(grid_crossing([-2.0, 5.0], [1.0, 0.0], [4.0, 3.0]), None, "passes beside");
        assert_eq!(grid_crossing([6.0, 1.0], [1.0, 0.0], [4.0, 3.0]), None, "behind the camera");
    }

    #[test]
    fn rays_enter_rock_through_the_side_top_or_underside() {
        let (side, span, depths) = (Facing::AlongX, [1.0, 2.0], [4.0, 5.0]);
        assert_eq!(entry(1.5, 0.0, span, depths, side), Some((4.0, Entry::Side(side))));
        let (t, face) = entry(3.0, -0.22, span, depths, side).unwrap();
        assert_eq!(face, Entry::Top);
        assert!((t - 1.0 / 0.22).abs() < 1e-12, "comes down onto the top within the cell");
        let (t, face) = entry(0.2, 0.19, span, depths, side).unwrap();
        assert_eq!(face, Entry::Underside);
        assert!((4.0..=5.0).contains(&t) && (0.2 + 0.19 * t - 1.0).abs() < 1e-9);
        assert_eq!(entry(0.2, 0.0, span, depths, side), None, "passes under");
        assert_eq!(entry(3.0, 0.0, span, depths, side), None, "passes over");
        assert_eq!(entry(3.0, -0.1, span, depths, side), None, "comes down beyond the cell");
    }
}
