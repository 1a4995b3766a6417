//! Boulders: rocks standing on the floor, each a union of convex faceted pieces. A piece is the
//! intersection of half-spaces that cut an ellipsoid at random depths, which gives the flat facets
//! of Unity's low-polygon rocks; a wide piece raised on a narrower one overhangs the floor.

use nalgebra::{Point3, Rotation3, Vector3};

use crate::obstacle::{CLEARANCE_M, Obstacle};
use crate::random::SplitMix64;

/// One half-space: the points `p` with `normal . p <= offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    /// Outward unit normal.
    pub normal: Vector3<f64>,
    /// Offset along the normal, metres.
    pub offset: f64,
}

/// A convex faceted piece of rock.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvexPiece {
    /// The half-spaces whose intersection is the piece.
    pub faces: Vec<HalfSpace>,
    /// Its corners (where three or more faces meet), metres.
    pub vertices: Vec<Point3<f64>>,
    /// For each face, its corners (indices into `vertices`) in order around it.
    pub face_corners: Vec<Vec<usize>>,
    /// Lower corner of the axis-aligned box around the piece (x, y, z), metres.
    pub min: Point3<f64>,
    /// Upper corner of the box.
    pub max: Point3<f64>,
}

/// An ellipsoid the piece is cut from: centre and half-axes, turned by `yaw_rad` about the vertical.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// Centre (x, y, z), metres; z is the height above the floor.
    pub centre: Point3<f64>,
    /// Half-axes along the turned x, the turned y and z, metres.
    pub radii: Vector3<f64>,
    /// Turn about the vertical, radians.
    pub yaw_rad: f64,
}

/// Number of facets of a piece.
const FACETS: usize = 26;
/// Facets cut the ellipsoid at 80 % to 100 % of its extent in their direction.
const FACET_DEPTH: (f64, f64) = (0.80, 1.0);
/// Every piece is cut flat this far below the floor, metres, so that it sits in the ground.
const BURIED_M: f64 = 0.3;

impl ConvexPiece {
    /// A faceted piece cut from `ellipsoid`, facets drawn from `rng`.
    pub fn cut(ellipsoid: &Ellipsoid, rng: &mut SplitMix64) -> Self {
        let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), ellipsoid.yaw_rad);
        let centre = ellipsoid.centre;
        let mut faces: Vec<HalfSpace> = fibonacci_directions(FACETS, rng.unit())
            .into_iter()
            .map(|direction| {
                let local = yaw.inverse_transform_vector(&direction);
                let support = ellipsoid.radii.component_mul(&local).norm();
                let depth = rng.range(FACET_DEPTH.0, FACET_DEPTH.1);
                HalfSpace { normal: direction, offset: direction.dot(&centre.coords) + depth * support }
            })
            .collect();
        faces.push(HalfSpace { normal: -Vector3::z(), offset: BURIED_M });
        let vertices = corners(&faces);
        let face_corners = faces.iter().map(|face| corners_around(face, &vertices)).collect();
        let min = vertices.iter().copied().reduce(|a, b| a.inf(&b)).unwrap_or(centre);
        let max = vertices.iter().copied().reduce(|a, b| a.sup(&b)).unwrap_or(centre);
        ConvexPiece { min, max, faces, vertices, face_corners }
    }

    /// True if the point (x, y, z) lies inside the piece.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        self.faces.iter().all(|f| f.normal.dot(&p.coords) <= f.offset)
    }
}

/// The corners of the intersection of `faces`: the points where three faces meet that lie inside
/// every other.
fn corners(faces: &[HalfSpace]) -> Vec<Point3<f64>> {
    let mut corners = Vec::new();
    for i in 0..faces.len() {
        for j in i + 1..faces.len() {
            for k in j + 1..faces.len() {
                let Some(p) = meeting_point(&faces[i], &faces[j], &faces[k]) else { continue };
                if faces.iter().all(|f| f.normal.dot(&p.coords) <= f.offset + 1e-7) {
                    corners.push(p);
                }
            }
        }
    }
    corners
}

/// The corners among `vertices` that lie on `face`, in order around it.
fn corners_around(face: &HalfSpace, vertices: &[Point3<f64>]) -> Vec<usize> {
    let mut on_face: Vec<usize> =
        (0..vertices.len()).filter(|&i| (face.normal.dot(&vertices[i].coords) - face.offset).abs() < 1e-6).collect();
    if on_face.is_empty() {
        return on_face;
    }
    let n = on_face.len() as f64;
    let centroid = on_face.iter().map(|&i| vertices[i].coords).sum::<Vector3<f64>>() / n;
    let helper = if face.normal.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let first = face.normal.cross(&helper).normalize();
    let second = face.normal.cross(&first);
    let angle = |i: usize| {
        let d = vertices[i].coords - centroid;
        d.dot(&second).atan2(d.dot(&first))
    };
    on_face.sort_by(|&a, &b| angle(a).total_cmp(&angle(b)));
    on_face.dedup_by(|a, b| (vertices[*a] - vertices[*b]).iter().all(|d| d.abs() < 1e-9));
    on_face
}

/// The point where the planes of three faces meet, if they do in one point.
fn meeting_point(a: &HalfSpace, b: &HalfSpace, c: &HalfSpace) -> Option<Point3<f64>> {
    let (bc, ca, ab) = (b.normal.cross(&c.normal), c.normal.cross(&a.normal), a.normal.cross(&b.normal));
    let determinant = a.normal.dot(&bc);
    if determinant.abs() < 1e-9 {
        return None;
    }
    Some(Point3::from((bc * a.offset + ca * b.offset + ab * c.offset) / determinant))
}

/// `n` directions spread evenly over the sphere (a Fibonacci lattice turned by `turn` of a circle).
fn fibonacci_directions(n: usize, turn: f64) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (i as f64 + 0.5) * 2.0 / n as f64;
            let ring = (1.0 - z * z).sqrt();
            let azimuth = golden * i as f64 + turn * std::f64::consts::TAU;
            Vector3::new(ring * azimuth.cos(), ring * azimuth.sin(), z)
        })
        .collect()
}

/// The shapes of rock the worlds use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoulderKind {
    /// One rounded lump resting on the floor.
    Lump,
    /// A lump with a smaller one leaning on it.
    Cluster,
    /// A wide cap raised on a lump: the floor runs on under its rim.
    Overhang(Cap),
    /// A tall column.
    Pillar,
}

/// The raised part of an overhanging boulder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cap {
    /// Centre of the cap relative to the boulder's centre (x, y), metres.
    pub offset_m: [f64; 2],
    /// Horizontal radius of the cap, metres.
    pub radius_m: f64,
    /// Height of its underside above the floor, metres.
    pub underside_m: f64,
    /// Its thickness, metres.
    pub thickness_m: f64,
}

/// A rock obstacle: one or more convex pieces.
#[derive(Debug, Clone, PartialEq)]
pub struct Boulder {
    /// Centre of the footprint (x, y), metres.
    pub centre: [f64; 2],
    /// The pieces.
    pub pieces: Vec<ConvexPiece>,
}

/// Where and how big a boulder is: the footprint radius is its extent at the floor; the rest of the
/// shape follows from the kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoulderSpec {
    /// Centre x, metres.
    pub x_m: f64,
    /// Centre y, metres.
    pub y_m: f64,
    /// Radius of the footprint on the floor, metres.
    pub footprint_radius_m: f64,
    /// Shape.
    pub kind: BoulderKind,
}

impl Boulder {
    /// A boulder of `spec`, its facets and proportions drawn from `rng`.
    pub fn new(spec: &BoulderSpec, rng: &mut SplitMix64) -> Self {
        let r = spec.footprint_radius_m;
        let yaw = rng.range(0.0, std::f64::consts::TAU);
        let mut ellipsoids = Vec::new();
        let (x, y) = (spec.x_m, spec.y_m);
        let stretch = rng.range(0.8, 1.2);
        match spec.kind {
            BoulderKind::Lump => {
                let height = r * rng.range(0.75, 1.1);
                ellipsoids.push(Ellipsoid {
                    centre: Point3::new(x, y, height * 0.3),
                    radii: Vector3::new(r * stretch, r / stretch, height * 0.75),
                    yaw_rad: yaw,
                });
            }
            BoulderKind::Cluster => {
                let height = r * rng.range(0.7, 1.0);
                let main = Vector3::new(r * 0.85 * stretch, r * 0.85 / stretch, height * 0.75);
                ellipsoids.push(Ellipsoid { centre: Point3::new(x, y, height * 0.3), radii: main, yaw_rad: yaw });
                let (s, c) = (yaw + 1.9).sin_cos();
                let side = Point3::new(x + c * r * 0.45, y + s * r * 0.45, height * 0.2);
                ellipsoids.push(Ellipsoid {
                    centre: side,
                    radii: Vector3::new(r * 0.55, r * 0.45, height * 0.5),
                    yaw_rad: yaw + 0.7,
                });
            }
            BoulderKind::Overhang(cap) => {
                let foot_top = cap.underside_m + cap.thickness_m / 2.0;
                ellipsoids.push(Ellipsoid {
                    centre: Point3::new(x, y, foot_top * 0.4),
                    radii: Vector3::new(r * stretch, r / stretch, foot_top * 0.8),
                    yaw_rad: yaw,
                });
                let half = cap.thickness_m / 2.0;
                let centre = Point3::new(x + cap.offset_m[0], y + cap.offset_m[1], cap.underside_m + half);
                ellipsoids.push(Ellipsoid {
                    centre,
                    radii: Vector3::new(cap.radius_m * stretch, cap.radius_m / stretch, half),
                    yaw_rad: yaw,
                });
            }
            BoulderKind::Pillar => {
                let height = r * rng.range(3.0, 4.0);
                ellipsoids.push(Ellipsoid {
                    centre: Point3::new(x, y, height * 0.45),
                    radii: Vector3::new(r, r * 0.85, height * 0.6),
                    yaw_rad: yaw,
                });
            }
        }
        let pieces = ellipsoids.iter().map(|e| ConvexPiece::cut(e, rng)).collect();
        Boulder { centre: [x, y], pieces }
    }

    /// True if any piece contains the point.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        self.pieces.iter().any(|piece| piece.contains(p))
    }

    /// Radius of a vertical cylinder around the centre that holds the whole boulder, metres.
    pub fn reach_m(&self) -> f64 {
        self.pieces
            .iter()
            .flat_map(|p| [[p.min.x, p.min.y], [p.max.x, p.max.y], [p.min.x, p.max.y], [p.max.x, p.min.y]])
            .map(|[x, y]| (x - self.centre[0]).hypot(y - self.centre[1]))
            .fold(0.0, f64::max)
    }
}

impl Obstacle for Boulder {
    /// Checked every 25 cm up from the clearance.
    fn covers(&self, x_m: f64, y_m: f64, ground_m: f64, up_to_m: f64) -> bool {
        (0..)
            .map(|k| CLEARANCE_M + 0.25 * k as f64)
            .take_while(|z| *z <= up_to_m)
            .any(|z| self.contains(&Point3::new(x_m, y_m, ground_m + z)))
    }

    fn bounds_m(&self) -> [[f64; 2]; 2] {
        let reach = self.reach_m();
        let [x, y] = self.centre;
        [[x - reach, y - reach], [x + reach, y + reach]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lump() -> ConvexPiece {
        let ellipsoid =
            Ellipsoid { centre: Point3::new(10.0, 20.0, 0.5), radii: Vector3::new(2.0, 1.0, 1.0), yaw_rad: 0.0 };
        ConvexPiece::cut(&ellipsoid, &mut SplitMix64::new(3))
    }

    #[test]
    fn a_piece_lies_within_its_ellipsoid_and_holds_most_of_it() {
        let piece = lump();
        assert!(piece.contains(&Point3::new(10.0, 20.0, 0.5)));
        assert!(!piece.contains(&Point3::new(12.1, 20.0, 0.5)) && !piece.contains(&Point3::new(10.0, 21.1, 0.5)));
        assert!(piece.contains(&Point3::new(11.4, 20.0, 0.5)), "80 % of the half-axis is always inside");
        assert!(!piece.contains(&Point3::new(10.0, 20.0, -0.35)), "cut flat below the floor");
        assert!(piece.vertices.len() >= 20, "{} corners", piece.vertices.len());
        for v in &piece.vertices {
            let on_faces = piece.faces.iter().filter(|f| (f.normal.dot(&v.coords) - f.offset).abs() < 1e-6).count();
            assert!(on_faces >= 3, "a corner lies on three faces: {v:?}");
        }
        assert!(piece.min.x >= 8.0 && piece.max.x <= 12.0 && piece.min.z >= -0.3 - 1e-9);
        let visible_faces = piece.face_corners.iter().filter(|corners| corners.len() >= 3).count();
        assert!(visible_faces >= 20, "most faces are polygons: {visible_faces}");
        for (face, corners) in piece.faces.iter().zip(&piece.face_corners) {
            for pair in corners.windows(2) {
                let (a, b) = (piece.vertices[pair[0]], piece.vertices[pair[1]]);
                let middle = nalgebra::center(&a, &b).coords;
                assert!((face.normal.dot(&middle) - face.offset).abs() < 1e-6, "edges lie on their face");
                assert!(piece.faces.iter().all(|f| f.normal.dot(&middle) <= f.offset + 1e-6), "and on the piece");
            }
        }
    }

    #[test]
    fn an_overhang_leaves_the_floor_free_under_its_rim() {
        let cap = Cap { offset_m: [0.0, 0.0], radius_m: 2.6, underside_m: 1.5, thickness_m: 2.0 };
        let spec = BoulderSpec { x_m: 50.0, y_m: 50.0, footprint_radius_m: 1.5, kind: BoulderKind::Overhang(cap) };
        for seed in 0..10 {
            let boulder = Boulder::new(&spec, &mut SplitMix64::new(seed));
            assert!(boulder.contains(&Point3::new(50.0, 50.0, 0.2)), "solid at the foot");
            let under_rim = (0..36).map(|k| (k as f64 * 10f64).to_radians()).find(|a| {
                let p = |z: f64| Point3::new(50.0 + 2.1 * a.cos(), 50.0 + 2.1 * a.sin(), z);
                !boulder.contains(&p(0.3)) && boulder.contains(&p(2.5))
            });
            assert!(under_rim.is_some(), "seed {seed}: somewhere the rim is above free floor");
            assert!(boulder.reach_m() > 2.2);
        }
    }
}
