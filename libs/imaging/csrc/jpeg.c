/* JPEG coding through the system's libjpeg-turbo (the libjpeg API), for src/jpeg.rs.
 *
 * Every libjpeg error, and every warning (corrupt data that libjpeg would otherwise decode on),
 * ends the call: the handler formats the message into the caller's buffer and jumps back to the
 * function that set up the call, which cleans up and returns ROVER_JPEG_FAILED. No Rust frame lies
 * between the setjmp and the longjmp. */

#include <setjmp.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>
#include <jerror.h>

#define ROVER_JPEG_OK 0
#define ROVER_JPEG_FAILED 1

/* The error manager of one call: libjpeg's, the way back, and where the message goes. */
struct guard {
    struct jpeg_error_mgr manager;
    jmp_buf back;
    char *message;
    size_t message_len;
};

static void fail(j_common_ptr info) {
    struct guard *guard = (struct guard *)info->err;
    char text[JMSG_LENGTH_MAX];
    (*info->err->format_message)(info, text);
    snprintf(guard->message, guard->message_len, "%s", text);
    longjmp(guard->back, 1);
}

/* Level -1 is a warning (corrupt data), which fails the call as an error does; higher levels are
 * trace messages, which are dropped. */
static void on_message(j_common_ptr info, int level) {
    if (level < 0) {
        fail(info);
    }
}

/* Most scans a JPEG may have. Each scan of a progressive JPEG is a pass over the whole image, so a
 * file of thousands of tiny scans would cost thousands of decodings; encoders write about ten. */
#define MAX_SCANS 100

/* A progress monitor that fails the call once the JPEG has more than MAX_SCANS scans. */
static void limit_scans(j_common_ptr info) {
    j_decompress_ptr decompress = (j_decompress_ptr)info;
    if (decompress->input_scan_number > MAX_SCANS) {
        struct guard *guard = (struct guard *)info->err;
        snprintf(guard->message, guard->message_len, "it has more than %d scans", MAX_SCANS);
        longjmp(guard->back, 1);
    }
}

static struct jpeg_error_mgr *guarded(struct guard *guard, char *message, size_t message_len) {
    struct jpeg_error_mgr *manager = jpeg_std_error(&guard->manager);
    manager->error_exit = fail;
    manager->emit_message = on_message;
    guard->message = message;
    guard->message_len = message_len;
    return manager;
}

/* A destination that grows one malloc'ed buffer, which the error path can free. */
struct growing_destination {
    struct jpeg_destination_mgr manager;
    unsigned char *buffer;
    size_t capacity;
};

static void start_destination(j_compress_ptr info) { (void)info; }

/* Called when the buffer is full: doubles it and carries on after what is written. */
static boolean grow_destination(j_compress_ptr info) {
    struct growing_destination *destination = (struct growing_destination *)info->dest;
    size_t capacity = destination->capacity * 2;
    unsigned char *buffer = realloc(destination->buffer, capacity);
    if (buffer == NULL) {
        ERREXIT1(info, JERR_OUT_OF_MEMORY, 0);
    }
    destination->manager.next_output_byte = buffer + destination->capacity;
    destination->manager.free_in_buffer = capacity - destination->capacity;
    destination->buffer = buffer;
    destination->capacity = capacity;
    return TRUE;
}

static void end_destination(j_compress_ptr info) { (void)info; }

/* Compresses the image's rows from `rgb`, 3 bytes a pixel. */
static void write_rows(j_compress_ptr info, const unsigned char *rgb) {
    size_t row_bytes = (size_t)info->image_width * 3;
    while (info->next_scanline < info->image_height) {
        JSAMPROW row = (JSAMPROW)(rgb + info->next_scanline * row_bytes);
        jpeg_write_scanlines(info, &row, 1);
    }
}

/* Encodes width x height RGB pixels as a baseline JFIF JPEG, 4:2:0, IJG `quality`, into a buffer
 * that starts at `capacity_hint` bytes (at least 1 kB) and grows as needed. On success *out is a
 * buffer of *out_len bytes for rover_jpeg_free. */
int rover_jpeg_encode(const unsigned char *rgb, int width, int height, int quality, size_t capacity_hint,
                      unsigned char **out, unsigned long *out_len, char *message, size_t message_len) {
    struct jpeg_compress_struct info;
    struct guard guard;
    struct growing_destination destination;
    *out = NULL;
    *out_len = 0;
    destination.capacity = capacity_hint < 1024 ? 1024 : capacity_hint;
    destination.buffer = malloc(destination.capacity);
    if (destination.buffer == NULL) {
        snprintf(message, message_len, "cannot allocate %zu bytes for the JPEG", destination.capacity);
        return ROVER_JPEG_FAILED;
    }
    destination.manager.next_output_byte = destination.buffer;
    destination.manager.free_in_buffer = destination.capacity;
    destination.manager.init_destination = start_destination;
    destination.manager.empty_output_buffer = grow_destination;
    destination.manager.term_destination = end_destination;
    info.err = guarded(&guard, message, message_len);
    if (setjmp(guard.back)) {
        jpeg_destroy_compress(&info);
        free(destination.buffer);
        return ROVER_JPEG_FAILED;
    }
    jpeg_create_compress(&info);
    info.dest = &destination.manager;
    info.image_width = (JDIMENSION)width;
    info.image_height = (JDIMENSION)height;
    info.input_components = 3;
    info.in_color_space = JCS_RGB;
    jpeg_set_defaults(&info);
    jpeg_set_quality(&info, quality, TRUE);
    jpeg_start_compress(&info, TRUE);
    write_rows(&info, rgb);
    jpeg_finish_compress(&info);
    *out = destination.buffer;
    *out_len = (unsigned long)(destination.capacity - destination.manager.free_in_buffer);
    jpeg_destroy_compress(&info);
    return ROVER_JPEG_OK;
}

/* Frees a buffer of rover_jpeg_encode. */
void rover_jpeg_free(unsigned char *buffer) { free(buffer); }

/* Decompresses rows first_row..end_row of the image into their places in `rgb`, 3 bytes a pixel:
 * the rows above are skipped (entropy-decoded only, as libjpeg must), those below not read. */
static void read_rows(j_decompress_ptr info, unsigned char *rgb, JDIMENSION first_row, JDIMENSION end_row) {
    size_t row_bytes = (size_t)info->output_width * 3;
    if (first_row > 0) {
        jpeg_skip_scanlines(info, first_row);
    }
    while (info->output_scanline < end_row) {
        JSAMPROW row = (JSAMPROW)(rgb + info->output_scanline * row_bytes);
        jpeg_read_scanlines(info, &row, 1);
    }
}

/* Reads the headers of `jpeg` and puts the image size in *width and *height. With `rgb`, and when
 * that size is rgb_width x rgb_height, also decodes rows first_row..end_row of the pixels into their
 * places in `rgb` (rgb_width * rgb_height * 3 bytes; the other rows are left as they are) the way
 * libjpeg-turbo's defaults do (accurate integer IDCT, smooth chroma upsampling), as OpenCV and PIL
 * decode; a JPEG of another size is not decoded. The rows decoded are the same, bit for bit, as in
 * a decoding of the whole image. */
int rover_jpeg_decode(const unsigned char *jpeg, unsigned long len, unsigned char *rgb, int rgb_width, int rgb_height,
                      int first_row, int end_row, int *width, int *height, char *message, size_t message_len) {
    struct jpeg_decompress_struct info;
    struct guard guard;
    info.err = guarded(&guard, message, message_len);
    if (setjmp(guard.back)) {
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    jpeg_create_decompress(&info);
    jpeg_mem_src(&info, jpeg, len);
    jpeg_read_header(&info, TRUE);
    *width = (int)info.image_width;
    *height = (int)info.image_height;
    if (rgb == NULL) {
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_OK;
    }
    if (*width != rgb_width || *height != rgb_height) {
        snprintf(message, message_len, "the image is %dx%d, expected %dx%d", *width, *height, rgb_width, rgb_height);
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    if (first_row < 0 || first_row > end_row || end_row > rgb_height) {
        snprintf(message, message_len, "rows %d..%d are not within the image's %d", first_row, end_row, rgb_height);
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    struct jpeg_progress_mgr progress = {.progress_monitor = limit_scans};
    info.progress = &progress;
    info.out_color_space = JCS_RGB;
    jpeg_start_decompress(&info);
    read_rows(&info, rgb, (JDIMENSION)first_row, (JDIMENSION)end_row);
    if (info.output_scanline == info.output_height) {
        jpeg_finish_decompress(&info);
    }
    jpeg_destroy_decompress(&info);
    return ROVER_JPEG_OK;
}
