//! A few-kB camera JPEG whose header claims 16384 x 16384 pixels is rejected from the header: the
//! error names both sizes and the process never allocates the 805 MB such an image would need.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use rover_imaging::{ImageError, RgbImage, encode_jpeg};
use rover_perception::classify::Thresholds;
use rover_perception::{Calibration, Perception, PerceptionError};

/// The system allocator, keeping the bytes in use and their peak.
struct CountingAllocator {
    in_use: AtomicUsize,
    peak: AtomicUsize,
}

// SAFETY: every call goes on to the system allocator with the caller's layout and pointer.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let in_use = self.in_use.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        self.peak.fetch_max(in_use, Ordering::Relaxed);
        // SAFETY: the caller's layout, as `GlobalAlloc::alloc` requires.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        self.in_use.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: `ptr` came from `alloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator { in_use: AtomicUsize::new(0), peak: AtomicUsize::new(0) };

/// Most the process may hold at once while rejecting the JPEG, bytes.
const PEAK_LIMIT_BYTES: usize = 10 << 20;

/// The JPEG with the height and width of its baseline frame header (SOF0) replaced.
fn claiming_size(mut jpeg: Vec<u8>, width: u16, height: u16) -> Vec<u8> {
    let sof0 = jpeg.windows(2).position(|marker| marker == [0xFF, 0xC0]).expect("a baseline JPEG has SOF0");
    jpeg[sof0 + 5..sof0 + 7].copy_from_slice(&height.to_be_bytes());
    jpeg[sof0 + 7..sof0 + 9].copy_from_slice(&width.to_be_bytes());
    jpeg
}

#[test]
fn a_jpeg_claiming_16384_by_16384_pixels_is_rejected_without_allocating_the_image() {
    let mut perception = Perception::new(Calibration::default(), Thresholds::default()).unwrap();
    let jpeg = claiming_size(encode_jpeg(&RgbImage::new(16, 16), 75).unwrap(), 16384, 16384);
    assert!(jpeg.len() < 4096, "a few kB: {} bytes", jpeg.len());
    ALLOCATOR.peak.store(ALLOCATOR.in_use.load(Ordering::Relaxed), Ordering::Relaxed);
    let baseline = ALLOCATOR.in_use.load(Ordering::Relaxed);

    let error = perception.process_jpeg(&jpeg).unwrap_err();

    let peak_bytes = ALLOCATOR.peak.load(Ordering::Relaxed) - baseline;
    assert!(peak_bytes < PEAK_LIMIT_BYTES, "rejecting the JPEG took {peak_bytes} bytes at its peak");
    let expected = ImageError::WrongSize { width: 16384, height: 16384, expected_width: 320, expected_height: 160 };
    assert_eq!(error, PerceptionError::Image(expected));
    assert_eq!(error.to_string(), "image is 16384x16384, expected 320x160");
}
