//! Drawing what stands on the terrain: boulders (convex faceted pieces, drawn face by face inside
//! each face's outline, the faces cut at the near plane) and the rock samples (spheres), each
//! against the depth of what is drawn.

use nalgebra::{Point3, Vector3};

use super::appearance::{Facing, fog_weights, scale3, shade, to_rgb8};
use super::columns::Painter;
use super::view::{LevelView, NEAR_M, Window, whole_pixels};
use super::{Hit, Surface};
use crate::boulder::{ConvexPiece, HalfSpace};
use crate::random::hash2;
use crate::world::World;

/// Albedo of the samples (Unity material colour 1.0, 0.848, 0.0 on a rock texture).
const SAMPLE_RGB: [f32; 3] = [232.0, 195.0, 20.0];
/// Pieces farther than this are not drawn, metres.
const MAX_PIECE_DEPTH_M: f64 = 290.0;
/// Samples are drawn between these depths, metres.
const SAMPLE_DEPTHS_M: (f64, f64) = (0.15, 40.0);

/// A boulder piece as the camera of one frame sees it.
pub(super) struct PieceInView<'a> {
    /// The piece.
    piece: &'a ConvexPiece,
    /// Its faces that face the camera, as far as they lie beyond the near plane.
    faces: Vec<FaceInView>,
}

/// A face of a piece that faces the camera of one frame.
pub(super) struct FaceInView {
    /// Its index among the piece's faces.
    face: usize,
    /// Its outline in the level view (column, row).
    outline: Vec<(f64, f64)>,
    /// How far the camera lies outside its plane, metres.
    room: f64,
    /// Its nearest forward depth, metres.
    nearest: f64,
}

/// The boulder pieces of `world` that can show in `window` of `view`, projected once for every
/// band of the frame: pieces wholly behind the camera, beside the window or too far off are left
/// out by their boxes first. A face reaching behind the near plane is cut there, so that what
/// is drawn of it lies ahead.
pub(super) fn pieces_in_view<'a>(world: &'a World, view: &LevelView, window: Window) -> Vec<PieceInView<'a>> {
    let mut pieces = Vec::new();
    for piece in world.boulders().iter().flat_map(|b| &b.pieces) {
        let corners: Vec<Option<(f64, f64, f64)>> = (0..8).map(|k| view.project(&box_corner(piece, k))).collect();
        if corners.iter().all(Option::is_none) {
            continue;
        }
        if corners.iter().all(Option::is_some) {
            let (lo_u, hi_u) =
                corners.iter().flatten().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.0), hi.max(c.0)));
            let nearest = corners.iter().flatten().map(|c| c.2).fold(f64::MAX, f64::min);
            if hi_u < window.u0 as f64 || lo_u > window.u1 as f64 || nearest > MAX_PIECE_DEPTH_M {
                continue;
            }
        }
        let projected: Vec<Option<(f64, f64, f64)>> = piece.vertices.iter().map(|v| view.project(v)).collect();
        let faces = piece
            .faces
            .iter()
            .zip(&piece.face_corners)
            .enumerate()
            .filter_map(|(face, (plane, corners))| {
                let room = plane.offset - plane.normal.dot(&view.camera.coords);
                if room >= 0.0 {
                    return None;
                }
                let (outline, nearest) = face_outline(piece, corners, &projected, view)?;
                Some(FaceInView { face, outline, room, nearest })
            })
            .collect();
        pieces.push(PieceInView { piece, faces });
    }
    pieces
}

/// The outline in the level view of the face of `piece` with `corners`, and its nearest forward
/// depth, given where the piece's vertices project (`None` for those not ahead of the near plane);
/// `None` if less than a polygon of it lies ahead.
fn face_outline(
    piece: &ConvexPiece,
    corners: &[usize],
    projected: &[Option<(f64, f64, f64)>],
    view: &LevelView,
) -> Option<(Vec<(f64, f64)>, f64)> {
    let outline_and_nearest = |points: &mut dyn Iterator<Item = (f64, f64, f64)>| {
        let mut nearest = f64::MAX;
        let outline: Vec<(f64, f64)> = points.inspect(|p| nearest = nearest.min(p.2)).map(|(u, v, _)| (u, v)).collect();
        (outline.len() >= 3).then_some((outline, nearest))
    };
    if corners.iter().all(|&i| projected[i].is_some()) {
        return outline_and_nearest(&mut corners.iter().filter_map(|&i| projected[i]));
    }
    let ahead = beyond_near_plane(corners.iter().map(|&i| piece.vertices[i]), view);
    outline_and_nearest(&mut ahead.iter().filter_map(|p| view.project_near(p)))
}

/// The part of a face polygon (its corners in order) that lies at least [`NEAR_M`] ahead of the
/// camera of `view`.
fn beyond_near_plane(corners: impl Iterator<Item = Point3<f64>>, view: &LevelView) -> Vec<Point3<f64>> {
    let corners: Vec<Point3<f64>> = corners.collect();
    let mut kept = Vec::with_capacity(corners.len() + 1);
    for (i, a) in corners.iter().enumerate() {
        let b = corners[(i + 1) % corners.len()];
        let (ahead_a, ahead_b) = (view.depth(a) - NEAR_M, view.depth(&b) - NEAR_M);
        if ahead_a >= 0.0 {
            kept.push(*a);
        }
        if (ahead_a < 0.0) != (ahead_b < 0.0) {
            kept.push(a + (b - a) * (ahead_a / (ahead_a - ahead_b)));
        }
    }
    kept
}

/// Corner `k` of a piece's box (bit a of `k` picks the upper bound of axis a).
fn box_corner(piece: &ConvexPiece, k: usize) -> Point3<f64> {
    let pick = |axis: usize| if k >> axis & 1 == 0 { piece.min[axis] } else { piece.max[axis] };
    Point3::new(pick(0), pick(1), pick(2))
}

impl Painter<'_, '_> {
    /// Draws a boulder piece where it is the nearest surface in the band's columns.
    pub(super) fn draw_piece(&mut self, piece: &PieceInView) {
        for face in &piece.faces {
            self.draw_face(&piece.piece.faces[face.face], face.room, &face.outline, face.nearest);
        }
    }

    /// Draws one face of a piece that faces the camera, whose outline on screen is `outline`:
    /// `room` is how far the camera lies outside its plane, `nearest` its nearest forward depth.
    fn draw_face(&mut self, face: &HalfSpace, room: f64, outline: &[(f64, f64)], nearest: f64) {
        let (view, appearance) = (&self.frame.view, self.frame.appearance);
        let Window { v0, v1, .. } = self.frame.window;
        let (lo_u, hi_u) = outline.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)));
        let columns = whole_pixels(lo_u, hi_u, self.band.columns.clone());
        let normal = face.normal;
        let sun = appearance.sunlight(&normal);
        let lit_rgb = appearance.boulder_rgb(sun);
        let facing = Facing::of_normal(&normal);
        for u in columns {
            let Some((top, bottom)) = column_span(outline, u as f64) else { continue };
            let rows = whole_pixels(top, bottom, v0..v1);
            let [dx, dy] = view.column_direction(u);
            let across = normal.x * dx + normal.y * dy;
            for v in rows {
                let index = self.index(u, v);
                if self.depth_at(index) <= nearest as f32 {
                    continue;
                }
                let rise = view.row_rise(v);
                let t = room / (across + normal.z * rise);
                if t <= NEAR_M || t as f32 >= self.depth_at(index) {
                    continue;
                }
                let point = (view.camera + Vector3::new(dx, dy, rise) * t).map(|c| c as f32);
                let (visible, haze) = fog_weights(t);
                let (a, b) = facing.texture_coordinates(point.x, point.y, point.z);
                let pixel = shade(scale3(lit_rgb, visible), appearance.rock_texel(a, b), haze);
                self.put(
                    index,
                    pixel,
                    Hit { surface: Surface::Boulder, depth_m: t as f32, height_m: point.z, sun, rock: 1.0 },
                );
            }
        }
    }

    /// Draws a sample: a sphere of `radius` around `centre`, where it is the nearest surface.
    pub(super) fn draw_sample(&mut self, centre: &Point3<f64>, radius: f64) {
        let view = &self.frame.view;
        let Some((u_mid, v_mid, depth)) = view.project(centre) else {
            return;
        };
        if !(SAMPLE_DEPTHS_M.0..=SAMPLE_DEPTHS_M.1).contains(&depth) {
            return;
        }
        let reach = view.focal_px * radius * 1.6 / depth + 1.0;
        let (columns, Window { v0, v1, .. }) = (self.band.columns.clone(), self.frame.window);
        let clamp_u = |p: f64| p.clamp(columns.start as f64, columns.end as f64) as usize;
        let clamp_v = |p: f64| p.clamp(v0 as f64, v1 as f64) as usize;
        let sun = self.frame.appearance.look.sun;
        let origin = view.camera - centre;
        for u in clamp_u(u_mid - reach)..clamp_u(u_mid + reach + 1.0) {
            let [dx, dy] = view.column_direction(u);
            for v in clamp_v(v_mid - reach)..clamp_v(v_mid + reach + 1.0) {
                let direction = Vector3::new(dx, dy, view.row_rise(v));
                let a = direction.norm_squared();
                let b = 2.0 * direction.dot(&origin);
                let c = origin.norm_squared() - radius * radius;
                let discriminant = b * b - 4.0 * a * c;
                if discriminant < 0.0 {
                    continue;
                }
                let t = (-b - discriminant.sqrt()) / (2.0 * a);
                let index = self.index(u, v);
                if t <= 0.0 || t as f32 >= self.depth_at(index) {
                    continue;
                }
                let normal = (origin + direction * t) / radius;
                let light = normal.dot(&sun).max(0.0);
                let texture = 0.85 + 0.3 * hash2((normal.x * 9.0) as i64, (normal.y * 9.0 + normal.z * 5.0) as i64, 31);
                let brightness = (0.55 + 0.5 * light) as f32 * texture;
                let height_m = (centre.z + origin.z + t * direction.z) as f32;
                let hit = Hit { surface: Surface::Sample, depth_m: t as f32, height_m, sun: light as f32, rock: 1.0 };
                self.put(index, to_rgb8(scale3(SAMPLE_RGB, brightness)), hit);
            }
        }
    }
}

/// A piece's faces as seen from the camera of one frame, for casting rays at it one by one: how
/// the tests check what is drawn face by face.
#[cfg(test)]
pub(super) struct FacesFromCamera {
    normals: Vec<Vector3<f32>>,
    /// How far the camera is inside each face's half-space (negative outside), metres.
    rooms: Vec<f32>,
}

#[cfg(test)]
impl FacesFromCamera {
    pub(super) fn new(piece: &ConvexPiece, camera: &Point3<f64>) -> Self {
        let room = |f: &HalfSpace| (f.offset - f.normal.dot(&camera.coords)) as f32;
        let normals = piece.faces.iter().map(|f| f.normal.map(|c| c as f32)).collect();
        let rooms = piece.faces.iter().map(room).collect();
        FacesFromCamera { normals, rooms }
    }

    /// The horizontal part of each face normal along a column's ray direction (dx, dy).
    pub(super) fn across_column(&self, dx: f64, dy: f64, out: &mut Vec<f32>) {
        out.clear();
        out.extend(self.normals.iter().map(|n| n.x * dx as f32 + n.y * dy as f32));
    }

    /// Where the ray of a row rising `rise` per metre (in the column of `across`) enters the
    /// piece: forward depth and the piece's face, if it does beyond the near plane.
    ///
    /// A face the ray moves out of (along < 0) bounds the entry from below at room / along, one it
    /// moves into bounds the exit from above; the ratios are compared by cross-multiplying (both
    /// denominators of a comparison have the same sign), so only the result needs a division.
    pub(super) fn entry(&self, across: &[f32], rise: f32) -> Option<(f32, usize)> {
        let (mut enter, mut exit) = ((-1.0f32, f32::MIN_POSITIVE), (1.0f32, 0.0f32));
        let mut face = usize::MAX;
        for (k, (across, (normal, room))) in across.iter().zip(self.normals.iter().zip(&self.rooms)).enumerate() {
            let (along, room) = (across + normal.z * rise, *room);
            if along < 0.0 {
                if face == usize::MAX || room * enter.1 > enter.0 * along {
                    (enter, face) = ((room, along), k);
                }
            } else if along > 0.0 {
                if room * exit.1 < exit.0 * along {
                    exit = (room, along);
                }
            } else if room < 0.0 {
                return None;
            }
        }
        if face == usize::MAX {
            return None;
        }
        let t = enter.0 / enter.1;
        let before_exit = exit.1 == 0.0 || t <= exit.0 / exit.1;
        (t > NEAR_M as f32 && before_exit).then_some((t, face))
    }
}

/// The rows (top, bottom) where the vertical line at column `u` crosses a convex outline. An
/// edge is followed from its leftmost end, so that faces sharing it meet without a gap.
fn column_span(outline: &[(f64, f64)], u: f64) -> Option<(f64, f64)> {
    let mut span: Option<(f64, f64)> = None;
    for (i, &a) in outline.iter().enumerate() {
        let b = outline[(i + 1) % outline.len()];
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        if (a.0 - u) * (b.0 - u) > 0.0 || a.0 == b.0 && a.0 != u {
            continue;
        }
        let rows = if a.0 == b.0 { [a.1, b.1] } else { [a.1 + (b.1 - a.1) * (u - a.0) / (b.0 - a.0); 2] };
        for v in rows {
            span = Some(span.map_or((v, v), |(top, bottom)| (top.min(v), bottom.max(v))));
        }
    }
    span
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boulder::Ellipsoid;
    use crate::random::SplitMix64;

    #[test]
    fn rays_enter_a_piece_through_the_facet_facing_them() {
        let ellipsoid =
            Ellipsoid { centre: Point3::new(10.0, 20.0, 0.5), radii: Vector3::new(2.0, 1.0, 1.0), yaw_rad: 0.0 };
        let piece = ConvexPiece::cut(&ellipsoid, &mut SplitMix64::new(3));
        let all = FacesFromCamera::new(&piece, &Point3::new(0.0, 20.0, 0.5));
        let mut across = Vec::new();
        all.across_column(1.0, 0.0, &mut across);
        let (t, face) = all.entry(&across, 0.0).expect("hits");
        assert!((8.0..=8.4).contains(&t), "enters between 80 % and 100 % of the half-axis: t = {t}");
        assert!(piece.faces[face].normal.x < -0.3, "the facet faces the ray");
        let inside = |x: f64| piece.contains(&Point3::new(x, 20.0, 0.5));
        assert!(inside(t as f64 + 0.01) && !inside(t as f64 - 0.01));
        let mut across = Vec::new();
        all.across_column(1.0, 0.5, &mut across);
        assert_eq!(all.entry(&across, 0.0), None, "passes beside");
        all.across_column(-1.0, 0.0, &mut across);
        assert_eq!(all.entry(&across, 0.0), None, "points away");
    }

    #[test]
    fn a_column_crosses_an_outline_between_its_edges() {
        let square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)];
        assert_eq!(column_span(&square, 1.0), Some((0.0, 2.0)));
        assert_eq!(column_span(&square, 3.0), None);
        let triangle = [(0.0, 0.0), (4.0, 0.0), (0.0, 4.0)];
        let (top, bottom) = column_span(&triangle, 1.0).unwrap();
        assert!((top - 0.0).abs() < 1e-12 && (bottom - 3.0).abs() < 1e-12);
        let reversed = [(0.0, 4.0), (4.0, 0.0), (0.0, 0.0)];
        assert_eq!(column_span(&reversed, 1.3), column_span(&triangle, 1.3), "the same edges give the same rows");
    }
}
