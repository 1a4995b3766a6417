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

#define ROVER_JPEG_OK 0
#define ROVER_JPEG_FAILED 1
#define ROVER_JPEG_WRONG_SIZE 2

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

/* Encodes width x height RGB pixels as a baseline JFIF JPEG, 4:2:0, IJG `quality`. On success
 * *out is a buffer of *out_len bytes for rover_jpeg_free. */
int rover_jpeg_encode(const unsigned char *rgb, int width, int height, int quality, unsigned char **out,
                      unsigned long *out_len, char *message, size_t message_len) {
    struct jpeg_compress_struct info;
    struct guard guard;
    *out = NULL;
    *out_len = 0;
    info.err = guarded(&guard, message, message_len);
    if (setjmp(guard.back)) {
        jpeg_destroy_compress(&info);
        free(*out);
        *out = NULL;
        return ROVER_JPEG_FAILED;
    }
    jpeg_create_compress(&info);
    jpeg_mem_dest(&info, out, out_len);
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
 * decode. A JPEG of another size is not decoded: ROVER_JPEG_WRONG_SIZE. */
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
        jpeg_destroy_decompress(&info);
        return ROVER_JPEG_WRONG_SIZE;
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
