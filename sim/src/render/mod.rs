//! The camera renderer: terrain, boulders, sky and the yellow samples, coloured, textured and
//! shaded like the Unity frames (unity-sim-spec 4.3), from the rover's camera.
//!
//! Each frame is first drawn for a level camera (yaw only) at the true camera position, in bands
//! of columns that threads draw side by side ([`columns`]): the terrain of every other column,
//! the columns between blended from their neighbours (edge by edge: an outline is not blurred),
//! then the boulders and samples over all columns ([`objects`]). Body pitch and roll are a pure rotation about
//! the camera centre, applied afterwards as an exact image-space resampling of the level view
//! ([`view`]). How things look is baked once per world ([`appearance`]).

mod appearance;
mod columns;
mod objects;
mod shadows;
mod surveyed;
mod view;

use rover_imaging::RgbImage;

use self::appearance::Appearance;
use self::columns::{Band, Frame, LevelRow, Painter, level_rows};
use self::surveyed::RockShading;
use self::view::{LevelView, MARGIN_PX, Rotation, Window};
use crate::camera::{BodyPose, CameraModel};
use crate::random::mix64;
use crate::world::{Sample, World};

/// Size of the sensor-noise table minus one (a power of two minus one).
const NOISE_MASK: usize = (1 << 16) - 1;
/// At most this many threads draw a frame.
const MAX_THREADS: usize = 4;

/// What a pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Surface {
    /// The floor (and the gentle foot of the walls, where it still has the floor's colour).
    Floor,
    /// A wall.
    Rock,
    /// A boulder.
    Boulder,
    /// The sky.
    Sky,
    /// A rock sample.
    Sample,
}

/// What the ray of a pixel hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// The surface.
    pub surface: Surface,
    /// Forward depth of the hit, metres (infinite for the sky).
    pub depth_m: f32,
    /// Height of the hit above the floor, metres.
    pub height_m: f32,
    /// How squarely the surface faces the sun, 0..1.
    pub sun: f32,
    /// How far the ground's colour has turned from floor to rock, 0..1 (1 off the terrain).
    pub rock: f32,
}

impl Hit {
    const SKY: Hit =
        Hit { surface: Surface::Sky, depth_m: f32::INFINITY, height_m: f32::INFINITY, sun: 0.0, rock: 1.0 };
}

/// Rendering options.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderOptions {
    /// Draw the 1 m calibration grid on the floor (the Unity "Grid" button).
    pub grid: bool,
    /// Keep what each pixel's ray hit, for [`Renderer::hits`].
    pub record_hits: bool,
}

/// Renders camera frames of one world.
pub struct Renderer {
    /// The sensor noise of each byte of a pixel, three per pixel, and then again as many pixels as
    /// a row has, so that the noise of any row is one slice.
    noise: Vec<i8>,
    camera: CameraModel,
    options: RenderOptions,
    appearance: Appearance,
    rock_shadings: Vec<RockShading>,
    rows: Vec<LevelRow>,
    threads: usize,
    /// Blend the terrain of every other column from its neighbours' (see [`Frame::blend_columns`]);
    /// never with the calibration grid, whose lines are a pixel wide.
    blend_columns: bool,
    level_width: usize,
    level_height: usize,
    level_rgb: Vec<[u8; 3]>,
    level_depth: Vec<f32>,
    level_hits: Vec<Hit>,
    hits: Vec<Hit>,
    frame: u64,
    /// The pose the level buffers were drawn for (none before the first frame)...
    drawn_pose: Option<BodyPose>,
    /// ...and the samples they show.
    drawn_samples: Vec<Sample>,
}

impl Renderer {
    /// A renderer for `world`, drawing with as many threads as there are cores (at most four).
    pub fn new(world: &World, camera: CameraModel, options: RenderOptions) -> Self {
        let (level_width, level_height) = (camera.width + 2 * MARGIN_PX, camera.height + 2 * MARGIN_PX);
        let level_pixels = level_width * level_height;
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, MAX_THREADS);
        let appearance = Appearance::new(world);
        Renderer {
            noise: noise_bytes(camera.width),
            camera,
            options,
            rock_shadings: world.surveyed_rocks().iter().map(|rock| RockShading::new(rock, &appearance)).collect(),
            appearance,
            rows: vec![LevelRow::default(); level_height],
            threads,
            blend_columns: !options.grid,
            level_width,
            level_height,
            level_rgb: vec![[0; 3]; level_pixels],
            level_depth: vec![f32::INFINITY; level_pixels],
            level_hits: if options.record_hits { vec![Hit::SKY; level_pixels] } else { Vec::new() },
            hits: if options.record_hits { vec![Hit::SKY; camera.width * camera.height] } else { Vec::new() },
            frame: 0,
            drawn_pose: None,
            drawn_samples: Vec::new(),
        }
    }

    /// What the ray of each pixel of the last frame hit, row-major like the image (empty unless
    /// the renderer was made with [`RenderOptions::record_hits`]).
    pub fn hits(&self) -> &[Hit] {
        &self.hits
    }

    /// Renders the camera view of the rover at `pose`, with `samples` on the ground, into `out`.
    /// A rover that has not moved (stopped, or picking up a sample) sees the scene it saw: only
    /// the sensor noise is new.
    pub fn render(&mut self, world: &World, samples: &[Sample], pose: &BodyPose, out: &mut RgbImage) {
        self.frame = self.frame.wrapping_add(1);
        let rotation = Rotation::new(pose, &self.camera);
        if self.drawn_pose.as_ref() != Some(pose) || self.drawn_samples != samples {
            self.draw(world, samples, pose, &rotation);
            self.drawn_pose = Some(*pose);
            self.drawn_samples.clear();
            self.drawn_samples.extend_from_slice(samples);
        }
        self.resample(&rotation, out);
    }

    /// Draws the level view of the rover at `pose` into the level buffers.
    fn draw(&mut self, world: &World, samples: &[Sample], pose: &BodyPose, rotation: &Rotation) {
        let view = LevelView::new(&self.camera, self.camera.position(pose), pose.yaw_deg);
        let window = Window::needed(rotation, &self.camera, (self.level_width, self.level_height));
        level_rows(&view, &self.appearance, &mut self.rows);
        let frame = Frame {
            world,
            samples,
            pieces: objects::pieces_in_view(world, &view, window),
            rocks: surveyed::rocks_in_view(world.surveyed_rocks(), &self.rock_shadings, &view, window),
            view,
            window,
            appearance: &self.appearance,
            rows: &self.rows,
            options: self.options,
            blend_columns: self.blend_columns,
            level_height: self.level_height,
        };
        draw_level(&frame, self.threads, &mut self.level_rgb, &mut self.level_depth, &mut self.level_hits);
    }

    /// Turns the level view into the camera image, rotating by the body's pitch and roll (nearest
    /// level pixel, as a native render would not blur), and adds the sensor noise; bands of rows
    /// on separate threads.
    fn resample(&mut self, rotation: &Rotation, out: &mut RgbImage) {
        let (width, height) = (self.camera.width, self.camera.height);
        if out.width != width || out.height != height {
            *out = RgbImage::new(width, height);
        }
        let rows_per_band = height.div_ceil(self.threads);
        let resampler = Resampler {
            rotation,
            level_rgb: &self.level_rgb,
            level_hits: &self.level_hits,
            level_height: self.level_height,
            level_width: self.level_width,
            noise: &self.noise,
            noise_offset: mix64(self.frame) as usize,
            width,
        };
        let hit_rows =
            self.hits.chunks_mut((rows_per_band * width).max(1)).map(Some).chain(std::iter::repeat_with(|| None));
        let bands = out.data.chunks_mut(rows_per_band * width * 3).zip(hit_rows).enumerate();
        run_split(bands, |(band, (rgb, hits))| resampler.rows(band * rows_per_band, rgb, hits));
    }
}

/// Runs `work` on each of `parts`: the first on this thread, each other on a thread of its own.
fn run_split<T: Send>(mut parts: impl Iterator<Item = T>, work: impl Fn(T) + Sync) {
    let own = parts.next();
    std::thread::scope(|scope| {
        for part in parts {
            let work = &work;
            scope.spawn(move || work(part));
        }
        if let Some(part) = own {
            work(part);
        }
    });
}

/// A non-negative `value` truncated to an index (beyond `i64` it saturates). The conversion goes
/// through `i64`, which the processor does in one instruction; straight to `usize` it takes
/// several, and the renderer does it for most pixels.
fn truncated_index(value: f64) -> usize {
    value as i64 as usize
}

/// Columns of a band. The threads of a frame take bands in turn, so that the work is shared evenly
/// whatever the view holds; the bands are the same whatever the number of threads, and so is the
/// image (a band blends columns from its own, [`columns::Painter::draw`]).
const BAND_COLUMNS: usize = 24;

/// Draws the level view of `frame` into the level buffers, in bands of columns taken in turn by
/// the threads.
fn draw_level(frame: &Frame, threads: usize, rgb: &mut [[u8; 3]], depth: &mut [f32], hits: &mut [Hit]) {
    let Window { u0, u1, .. } = frame.window;
    let height = frame.level_height;
    let (mut rgb, mut depth) = (&mut rgb[u0 * height..u1 * height], &mut depth[u0 * height..u1 * height]);
    let mut hits = if hits.is_empty() { hits } else { &mut hits[u0 * height..u1 * height] };
    let mut work: Vec<Vec<Band>> = (0..threads).map(|_| Vec::new()).collect();
    for (number, first) in (u0..u1).step_by(BAND_COLUMNS).enumerate() {
        let columns = first..(first + BAND_COLUMNS).min(u1);
        let pixels = columns.len() * height;
        let hit_pixels = pixels.min(hits.len());
        let (band_rgb, rest_rgb) = std::mem::take(&mut rgb).split_at_mut(pixels);
        let (band_depth, rest_depth) = std::mem::take(&mut depth).split_at_mut(pixels);
        let (band_hits, rest_hits) = std::mem::take(&mut hits).split_at_mut(hit_pixels);
        (rgb, depth, hits) = (rest_rgb, rest_depth, rest_hits);
        work[number % threads].push(Band { columns, rgb: band_rgb, depth: band_depth, hits: band_hits });
    }
    run_split(work.into_iter(), |bands: Vec<Band>| {
        for band in bands {
            Painter { frame, band }.draw();
        }
    });
}

/// The noise table of [`Renderer::noise`] for images `width` pixels wide: -3..=3 per pixel.
fn noise_bytes(width: usize) -> Vec<i8> {
    (0..=NOISE_MASK + width).flat_map(|i| [(mix64((i & NOISE_MASK) as u64) % 7) as i8 - 3; 3]).collect()
}

/// `value` plus `noise`, saturated to a byte (in the signed domain, where the processor
/// saturates by itself).
fn add_noise(value: u8, noise: i8) -> u8 {
    ((value ^ 0x80) as i8).saturating_add(noise) as u8 ^ 0x80
}

/// What the rows of the camera image are made from.
struct Resampler<'a> {
    rotation: &'a Rotation,
    level_rgb: &'a [[u8; 3]],
    level_hits: &'a [Hit],
    level_width: usize,
    level_height: usize,
    noise: &'a [i8],
    noise_offset: usize,
    width: usize,
}

impl Resampler<'_> {
    /// Fills the image rows from `first_row` on (`rgb`, and `hits` when recording): where each
    /// pixel comes from in the level view, then the pixels row by row (a row reads one pixel of
    /// each level column, and the next row the pixels below them, which are in the cache by then).
    fn rows(&self, first_row: usize, rgb: &mut [u8], hits: Option<&mut [Hit]>) {
        let rows = rgb.len() / (self.width * 3);
        let sources = self.sources(first_row, rows);
        let image_rows = rgb.chunks_exact_mut(self.width * 3).zip(sources.chunks_exact(self.width));
        for (v, (out_row, source_row)) in (first_row..).zip(image_rows) {
            for (out, &source) in out_row.chunks_exact_mut(3).zip(source_row) {
                out.copy_from_slice(&self.level_rgb[source as usize]);
            }
            let noise_start = self.noise_offset.wrapping_add(v * self.width) & NOISE_MASK;
            let noise = &self.noise[noise_start * 3..][..self.width * 3];
            for (channel, &noise) in out_row.iter_mut().zip(noise) {
                *channel = add_noise(*channel, noise);
            }
        }
        if let Some(hits) = hits.filter(|h| !h.is_empty()) {
            for (hit, &source) in hits.iter_mut().zip(&sources) {
                *hit = self.level_hits[source as usize];
            }
        }
    }

    /// The level-view index each pixel of `rows` image rows from `first_row` on is taken from.
    /// Tilted, the exact projection is computed every [`SEGMENT_PX`] pixels of a row, clamped to
    /// the level view, and followed in between in 16.16 fixed point (a rotation of a few degrees
    /// bends it by far less than a pixel there).
    fn sources(&self, first_row: usize, rows: usize) -> Vec<u32> {
        const SEGMENT_PX: usize = 16;
        let height = self.level_height;
        let mut sources = Vec::with_capacity(rows * self.width);
        if self.rotation.is_identity() {
            for v in first_row..first_row + rows {
                sources.extend((0..self.width).map(|u| ((u + MARGIN_PX) * height + v + MARGIN_PX) as u32));
            }
            return sources;
        }
        let map = self.rotation.pixel_map();
        let (max_u, max_v) = ((self.level_width - 1) as f32, (height - 1) as f32);
        let nearest_fixed = |(lu, lv): (f32, f32)| {
            let fixed = |value: f32, max: f32| ((value + 0.5).clamp(0.0, max) * FIXED_PX) as i32;
            (fixed(lu, max_u), fixed(lv, max_v))
        };
        for v in first_row..first_row + rows {
            let mut from = nearest_fixed(map.level_pixel(0, v));
            for start in (0..self.width).step_by(SEGMENT_PX) {
                let to = nearest_fixed(map.level_pixel(start + SEGMENT_PX, v));
                let per_px = ((to.0 - from.0) / SEGMENT_PX as i32, (to.1 - from.1) / SEGMENT_PX as i32);
                let (mut lu, mut lv) = from;
                sources.extend((start..(start + SEGMENT_PX).min(self.width)).map(|_| {
                    let source = (lu >> FIXED_PX_BITS) as u32 * height as u32 + (lv >> FIXED_PX_BITS) as u32;
                    (lu, lv) = (lu + per_px.0, lv + per_px.1);
                    source
                }));
                from = to;
            }
        }
        sources
    }
}

/// Fractional bits of the level-view coordinates followed along a segment of an image row...
const FIXED_PX_BITS: u32 = 16;
/// ...and one pixel in them.
const FIXED_PX: f32 = (1 << FIXED_PX_BITS) as f32;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::{StartPose, WORLD_SIZE};

    #[test]
    fn a_level_camera_on_open_floor_sees_floor_below_the_horizon_and_sky_above() {
        let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
        let world = World::open(floor, StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 });
        let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
        let mut renderer = Renderer::new(&world, CameraModel::rover(), options);
        let mut image = RgbImage::default();
        renderer.render(&world, &[], &BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() }, &mut image);
        let surface = |u: usize, v: usize| renderer.hits()[v * 320 + u].surface;
        assert_eq!(surface(160, 150), Surface::Floor);
        assert_eq!(surface(160, 10), Surface::Sky);
        assert_eq!(surface(160, 60), Surface::Rock, "the world's edge is a wall 100 m away, 38.7 m high");
        let [r, g, b] = image.pixel(160, 150);
        assert!(r > 200 && g > 190 && b > 180, "bright floor: {:?}", [r, g, b]);
    }

    /// An open world with an overhanging boulder and a cluster of pieces ahead of (100, 100).
    fn world_with_boulders() -> World {
        use crate::boulder::{Boulder, BoulderKind, BoulderSpec, Cap};
        use crate::random::SplitMix64;
        let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
        let cap = Cap { offset_m: [-1.0, 0.5], radius_m: 2.5, underside_m: 1.6, thickness_m: 2.0 };
        let specs = [
            BoulderSpec { x_m: 106.0, y_m: 100.5, footprint_radius_m: 1.2, kind: BoulderKind::Overhang(cap) },
            BoulderSpec { x_m: 103.0, y_m: 97.5, footprint_radius_m: 0.8, kind: BoulderKind::Cluster },
        ];
        let boulders = specs.iter().map(|spec| Boulder::new(spec, &mut SplitMix64::new(5))).collect();
        let start = crate::world::StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 };
        let plan = crate::world::WorldPlan {
            ground_truth: floor.clone(),
            floor,
            boulders,
            surveyed_rocks: vec![],
            samples: vec![],
            start,
            ground: crate::world::Ground::Generated { salt: 0 },
        };
        World::build(plan)
    }

    /// Renders `world` from `pose` and casts every pixel's ray at every boulder piece: how many
    /// pixels show a boulder, and at how many the drawing and the ray disagree about it.
    fn boulder_pixels_and_disagreements(world: &World, pose: &BodyPose) -> (usize, usize) {
        let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
        let camera = CameraModel::rover();
        let mut renderer = Renderer::new(world, camera, options);
        renderer.render(world, &[], pose, &mut RgbImage::default());
        let view = LevelView::new(&camera, camera.position(pose), pose.yaw_deg);
        let faces: Vec<_> = world
            .boulders()
            .iter()
            .flat_map(|b| &b.pieces)
            .map(|p| objects::FacesFromCamera::new(p, &view.camera))
            .collect();
        let (mut boulder_pixels, mut disagreements) = (0, 0);
        let mut across = Vec::new();
        for (index, hit) in renderer.hits().iter().enumerate() {
            let (u, v) = (index % 320 + MARGIN_PX, index / 320 + MARGIN_PX);
            let [dx, dy] = view.column_direction(u);
            let nearest = faces
                .iter()
                .filter_map(|f| {
                    f.across_column(dx, dy, &mut across);
                    f.entry(&across, view.row_rise(v) as f32).map(|(t, _)| t)
                })
                .fold(f32::INFINITY, f32::min);
            let agrees = if hit.surface == Surface::Boulder {
                boulder_pixels += 1;
                (hit.depth_m - nearest).abs() < 1e-3 * nearest
            } else {
                nearest >= hit.depth_m * (1.0 - 1e-3)
            };
            disagreements += !agrees as usize;
        }
        (boulder_pixels, disagreements)
    }

    #[test]
    fn boulders_drawn_face_by_face_are_where_their_rays_meet_them() {
        let world = world_with_boulders();
        let pose = BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() };
        let (boulder_pixels, disagreements) = boulder_pixels_and_disagreements(&world, &pose);
        assert!(boulder_pixels > 2000, "{boulder_pixels} boulder pixels");
        assert!(
            disagreements * 100 < boulder_pixels,
            "{disagreements} of {boulder_pixels} pixels disagree at the outlines"
        );
    }

    #[test]
    fn a_boulder_reaching_behind_the_camera_is_drawn_where_its_rays_meet_it() {
        let world = world_with_boulders();
        let pose = BodyPose { x_m: 102.6, y_m: 98.9, yaw_deg: -20.0, ..Default::default() };
        let camera = CameraModel::rover();
        let view = LevelView::new(&camera, camera.position(&pose), pose.yaw_deg);
        let straddles = |piece: &crate::boulder::ConvexPiece| {
            let depths = piece.vertices.iter().map(|p| view.depth(p));
            let (nearest, farthest) = depths.fold((f64::MAX, f64::MIN), |(lo, hi), d| (lo.min(d), hi.max(d)));
            nearest < view::NEAR_M && farthest > 1.0
        };
        assert!(world.boulders().iter().flat_map(|b| &b.pieces).any(straddles), "a piece reaches behind the camera");
        let (boulder_pixels, disagreements) = boulder_pixels_and_disagreements(&world, &pose);
        assert!(boulder_pixels > 5000, "{boulder_pixels} boulder pixels");
        assert!(
            disagreements * 100 < boulder_pixels,
            "{disagreements} of {boulder_pixels} pixels disagree at the outlines"
        );
    }

    /// An open world with a surveyed rock ahead of (100, 100): a dome of 0.25 m columns, standing
    /// on the floor in its middle and raised 0.6 m off it under its rim.
    fn world_with_a_surveyed_rock() -> World {
        let (cols, cell_m, origin) = (14, 0.25, [101.75, 98.25]);
        let grid = |value: &dyn Fn(f64) -> Option<f64>| {
            let rows: Vec<String> = (0..cols)
                .map(|r| {
                    let cells: Vec<String> = (0..cols)
                        .map(|c| {
                            let radius = ((c as f64 + 0.5 - cols as f64 / 2.0)
                                .hypot(r as f64 + 0.5 - cols as f64 / 2.0))
                                * cell_m;
                            value(radius).map_or("null".into(), |v| format!("{v:.2}"))
                        })
                        .collect();
                    format!("[{}]", cells.join(","))
                })
                .collect();
            format!("[{}]", rows.join(","))
        };
        let top = grid(&|r| (r < 1.7).then_some(1.6 - r * 0.5));
        let bottom = grid(&|r| (r < 1.7).then_some(if r < 0.9 { 0.0 } else { 0.6 }));
        let json = format!(
            r#"{{"rocks": [{{"cell_m": {cell_m}, "origin": [{}, {}], "rows": {cols}, "cols": {cols}, "bottom_m": {bottom}, "top_m": {top}}}]}}"#,
            origin[0], origin[1]
        );
        let floor = vec![true; WORLD_SIZE * WORLD_SIZE];
        let plan = crate::world::WorldPlan {
            ground_truth: floor.clone(),
            floor,
            boulders: vec![],
            surveyed_rocks: crate::rock_survey::read_rock_survey(json.as_bytes()).unwrap(),
            samples: vec![],
            start: crate::world::StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 },
            ground: crate::world::Ground::Generated { salt: 0 },
        };
        World::build(plan)
    }

    #[test]
    fn surveyed_rocks_are_drawn_where_their_rays_meet_their_columns() {
        let world = world_with_a_surveyed_rock();
        let camera = CameraModel::rover();
        for pose in [
            BodyPose { x_m: 100.0, y_m: 100.0, ..Default::default() },
            BodyPose { x_m: 101.0, y_m: 98.0, yaw_deg: 35.0, ..Default::default() },
            BodyPose { x_m: 100.5, y_m: 100.0, ground_m: 1.0, ..Default::default() },
        ] {
            let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
            let mut renderer = Renderer::new(&world, camera, options);
            renderer.render(&world, &[], &pose, &mut RgbImage::default());
            let view = LevelView::new(&camera, camera.position(&pose), pose.yaw_deg);
            let rock = &world.surveyed_rocks()[0];
            let (mut rock_pixels, mut disagreements, mut floor_under_rim) = (0, 0, 0);
            for (index, hit) in renderer.hits().iter().enumerate() {
                let (u, v) = (index % 320 + MARGIN_PX, index / 320 + MARGIN_PX);
                let [dx, dy] = view.column_direction(u);
                let rise = view.row_rise(v);
                let inside = |t: f64| {
                    let p = view.camera + nalgebra::Vector3::new(dx, dy, rise) * t;
                    rock.column_at(p.x, p.y).is_some_and(|c| (c.bottom_m as f64..=c.top_m as f64).contains(&p.z))
                };
                let nearest = (1..4000).map(|k| k as f64 * 0.002).find(|&t| inside(t));
                let agrees = match (hit.surface == Surface::Boulder, nearest) {
                    (true, Some(t)) => (hit.depth_m as f64 - t).abs() < 0.01 + 0.01 * t,
                    (false, Some(t)) => t >= hit.depth_m as f64 - 0.01,
                    (true, None) => false,
                    (false, None) => true,
                };
                rock_pixels += (hit.surface == Surface::Boulder) as usize;
                disagreements += !agrees as usize;
                let p = view.camera + nalgebra::Vector3::new(dx, dy, rise) * hit.depth_m as f64;
                floor_under_rim += (hit.surface == Surface::Floor && rock.column_at(p.x, p.y).is_some()) as usize;
            }
            assert!(rock_pixels > 3000, "{rock_pixels} rock pixels");
            assert!(disagreements * 100 < rock_pixels, "{disagreements} of {rock_pixels} pixels disagree");
            if pose.ground_m == 0.0 {
                assert!(floor_under_rim > 50, "the floor shows under the raised rim: {floor_under_rim} pixels");
            }
        }
    }

    /// The body at the start of `world` on level ground, with the given yaw, pitch and roll.
    fn at_start(world: &World, yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> BodyPose {
        BodyPose { x_m: world.start.x_m, y_m: world.start.y_m, yaw_deg, pitch_deg, roll_deg, ground_m: 0.0 }
    }

    #[test]
    fn a_rover_that_has_not_moved_sees_what_a_fresh_drawing_shows() {
        let world = crate::procgen::procedural_world(3);
        let here = at_start(&world, 10.0, 1.5, 0.0);
        let elsewhere = BodyPose { yaw_deg: 100.0, ..here };
        let sample = Sample { x_m: here.x_m + 3.0, y_m: here.y_m + 0.5, radius_m: 0.2 };
        let second_frame = |first: (&BodyPose, &[Sample]), second: (&BodyPose, &[Sample])| {
            let mut renderer = Renderer::new(&world, CameraModel::rover(), RenderOptions::default());
            let mut image = RgbImage::default();
            renderer.render(&world, first.1, first.0, &mut image);
            renderer.render(&world, second.1, second.0, &mut image);
            image
        };
        let kept = second_frame((&here, &[sample]), (&here, &[sample]));
        assert_eq!(kept.data, second_frame((&elsewhere, &[sample]), (&here, &[sample])).data);
        let picked_up = second_frame((&here, &[sample]), (&here, &[]));
        assert_eq!(picked_up.data, second_frame((&elsewhere, &[]), (&here, &[])).data);
        assert_ne!(kept.data, picked_up.data, "the sample is in view");
    }

    /// The frame of `world` with its samples from `pose`, drawn by a renderer that `configure` set up.
    fn frame_of(world: &World, pose: &BodyPose, configure: impl FnOnce(&mut Renderer)) -> RgbImage {
        let mut renderer = Renderer::new(world, CameraModel::rover(), RenderOptions::default());
        configure(&mut renderer);
        let mut image = RgbImage::default();
        renderer.render(world, &world.samples, pose, &mut image);
        image
    }

    #[test]
    fn blended_columns_look_like_drawn_ones() {
        let (mut byte_difference, mut bytes, mut far_off_pixels) = (0u64, 0u64, 0usize);
        for seed in [1, 2, 3] {
            let world = crate::procgen::procedural_world(seed);
            for yaw_deg in [0.0, 70.0, 160.0, 250.0] {
                let pose = at_start(&world, yaw_deg, 1.0, -1.5);
                let frame_with = |blend_columns| frame_of(&world, &pose, |r| r.blend_columns = blend_columns);
                let (blended, drawn) = (frame_with(true), frame_with(false));
                assert_ne!(blended.data, drawn.data, "seed {seed} yaw {yaw_deg}: nothing blended");
                for (b, d) in blended.data.chunks_exact(3).zip(drawn.data.chunks_exact(3)) {
                    let differences = [0, 1, 2].map(|c| b[c].abs_diff(d[c]));
                    byte_difference += differences.iter().map(|&x| x as u64).sum::<u64>();
                    bytes += 3;
                    far_off_pixels += (differences.into_iter().max().unwrap() > 48) as usize;
                }
            }
        }
        let (mean, far_off) = (byte_difference as f64 / bytes as f64, far_off_pixels as f64 / (bytes / 3) as f64);
        assert!(mean < 1.0, "blended frames differ by {mean:.2} levels a byte on average");
        assert!(far_off < 0.005, "{:.2} % of the pixels differ by more than 48 levels", far_off * 100.0);
    }

    #[test]
    fn a_sample_in_view_shows_as_well_in_blended_columns() {
        let world = crate::procgen::procedural_world(2);
        let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
        let mut renderers = [true, false].map(|blend_columns| {
            let mut renderer = Renderer::new(&world, CameraModel::rover(), options);
            renderer.blend_columns = blend_columns;
            renderer
        });
        let (mut views, mut blended_pixels, mut drawn_pixels) = (0, 0, 0);
        for sample in &world.samples {
            for bearing_deg in (0..24).map(|k| k as f64 * 15.0) {
                for distance_m in [2.0, 3.0, 4.5, 6.0, 8.0] {
                    let (sin, cos) = bearing_deg.to_radians().sin_cos();
                    let (x_m, y_m) = (sample.x_m + distance_m * cos, sample.y_m + distance_m * sin);
                    if !world.is_drivable(x_m, y_m) {
                        continue;
                    }
                    let ground_m = world.ground_height(x_m, y_m) as f64;
                    let yaw_deg = bearing_deg + 180.0 + 10.0;
                    let pose = BodyPose { x_m, y_m, yaw_deg, pitch_deg: 0.5, roll_deg: -0.5, ground_m };
                    let [blended, drawn] = renderers.each_mut().map(|renderer| {
                        renderer.render(&world, &world.samples, &pose, &mut RgbImage::default());
                        renderer.hits().iter().filter(|hit| hit.surface == Surface::Sample).count()
                    });
                    if drawn > 0 {
                        assert!(
                            blended > 0,
                            "the sample at ({:.1}, {:.1}) is lost from ({x_m:.1}, {y_m:.1})",
                            sample.x_m,
                            sample.y_m
                        );
                        (views, blended_pixels, drawn_pixels) =
                            (views + 1, blended_pixels + blended, drawn_pixels + drawn);
                    }
                }
            }
        }
        assert!(views > 100, "{views} views show a sample");
        assert!(
            blended_pixels * 100 >= drawn_pixels * 99,
            "{blended_pixels} sample pixels blended, {drawn_pixels} drawn"
        );
    }

    #[test]
    fn threads_draw_the_same_frame_as_one() {
        let world = crate::procgen::procedural_world(2);
        let pose = at_start(&world, 30.0, 3.0, -2.0);
        let frame_with = |threads| frame_of(&world, &pose, |r| r.threads = threads);
        let one = frame_with(1);
        assert_eq!(one.data, frame_with(2).data);
        assert_eq!(one.data, frame_with(3).data);
    }
}
