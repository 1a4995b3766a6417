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
mod tests;
