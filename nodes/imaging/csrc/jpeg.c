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
    while (info.next_scanline < info.image_height) {
        JSAMPROW row = (JSAMPROW)(rgb + (size_t)info.next_scanline * (size_t)width * 3);
        jpeg_write_scanlines(&info, &row, 1);
    }
    jpeg_finish_compress(&info);
    *out = destination.buffer;
    *out_len = (unsigned long)(destination.capacity - destination.manager.free_in_buffer);
    jpeg_destroy_compress(&info);
    return ROVER_JPEG_OK;
}

/* Frees a buffer of rover_jpeg_encode. */
void rover_jpeg_free(unsigned char *buffer) { free(buffer); }

/* Reads the headers of `jpeg` into `info` (created here; the caller destroys it). */
static void read_header(struct jpeg_decompress_struct *info, const unsigned char *jpeg, unsigned long len) {
    jpeg_create_decompress(info);
    jpeg_mem_src(info, jpeg, len);
    jpeg_read_header(info, TRUE);
}

/* The image size that the headers of `jpeg` give. */
int rover_jpeg_dimensions(const unsigned char *jpeg, unsigned long len, int *width, int *height, char *message,
                          size_t message_len) {
    struct jpeg_decompress_struct info;
    struct guard guard;
    info.err = guarded(&guard, message, message_len);
    if (setjmp(guard.back)) {
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    read_header(&info, jpeg, len);
    *width = (int)info.image_width;
    *height = (int)info.image_height;
    jpeg_destroy_decompress(&info);
    return ROVER_JPEG_OK;
}

/* Decodes `jpeg` into width x height RGB pixels at `rgb` (width * height * 3 bytes), the way
 * libjpeg-turbo's defaults do (accurate integer IDCT, smooth chroma upsampling), as OpenCV and PIL
 * decode. A JPEG of another size is not decoded. */
int rover_jpeg_decode_rgb(const unsigned char *jpeg, unsigned long len, unsigned char *rgb, int width, int height,
                          char *message, size_t message_len) {
    struct jpeg_decompress_struct info;
    struct guard guard;
    info.err = guarded(&guard, message, message_len);
    if (setjmp(guard.back)) {
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    read_header(&info, jpeg, len);
    if (info.image_width != (JDIMENSION)width || info.image_height != (JDIMENSION)height) {
        snprintf(message, message_len, "the image is %ux%u, expected %dx%d", (unsigned)info.image_width,
                 (unsigned)info.image_height, width, height);
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_FAILED;
    }
    info.out_color_space = JCS_RGB;
    jpeg_start_decompress(&info);
    while (info.output_scanline < info.output_height) {
        JSAMPROW row = (JSAMPROW)(rgb + (size_t)info.output_scanline * (size_t)width * 3);
        jpeg_read_scanlines(&info, &row, 1);
    }
    jpeg_finish_decompress(&info);
    jpeg_destroy_decompress(&info);
    return ROVER_JPEG_OK;
}
