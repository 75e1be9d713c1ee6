// image_oiio.cpp - the C shim over OpenImageIO's DDS reader (image_oiio.h says what it gives),
// built as its own plugin, reflcheck-oiio.so, which image_dds.c loads at the first DDS read.
// C++ stays in this file: no exception and no C++ type crosses the C interface. Its three entry
// points carry the plugin's own names, so that they never resolve to image_dds.c's.

// The C headers first, with C linkage; image_oiio.h's include of status.h is then a no-op.
extern "C" {
#include "fileio.h"
#include "status.h"
}
#include "image_oiio.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

extern "C" const char *reflcheck_oiio_version(void);

namespace {

// OpenImageIO joins its messages with newlines (a short read repeats one per tile); ours are one
// line, so the first message stands for them.
std::string one_line(std::string s)
{
    s = s.substr(0, s.find_first_of("\r\n"));
    return s.empty() ? std::string("no reason given") : s;
}

// What to do about a DDS OpenImageIO 2.4 cannot decode (measured: docs/cubemaps.md).
const char *const dds_fix = "re-save it as DXT1/DXT5 (BC1/BC3) with a legacy header, BC7_UNORM, or uncompressed "
                            "A8R8G8B8";

rc_status check_kind(const char *path, const OIIO::ImageSpec &spec, image_dds_kind kind, int *w, int *h, int *faces,
                     char *err, size_t errlen)
{
    std::string tf = spec.get_string_attribute("textureformat");
    bool cube = tf == "CubeFace Environment";
    if (kind == IMAGE_DDS_CUBE && !cube) {
        status_message(err, errlen,
                       "%s: a DDS %s (%dx%d), not a cube map (no DDSCAPS2_CUBEMAP); give a DDS cube map with all six "
                       "faces, or the faces as six images under environment.cube",
                       path, tf == "Volume Texture" ? "volume texture" : "2D image", spec.width, spec.height);
        return RC_ERR_RANGE;
    }
    if (kind == IMAGE_DDS_2D && tf != "Plain Texture") {
        status_message(err, errlen, "%s: a DDS %s, not a 2D image; give a 2D DDS here%s", path,
                       cube ? "cube map" : "volume texture", cube ? " (a cube map goes under environment.cube_dds)" : "");
        return RC_ERR_RANGE;
    }
    if (!cube) {
        *w = spec.width;
        *h = spec.height;
        *faces = 1;
        return RC_OK;
    }
    // A cube is a 1 x 6 strip of face-sized tiles (OpenImageIO 2.4's DDS layout).
    std::string sides = spec.get_string_attribute("dds:CubeMapSides");
    if (sides != "+x -x +y -y +z -z") {
        status_message(err, errlen,
                       "%s: a DDS cube map with the faces '%s' only; give one with all six faces (+x -x +y -y +z -z)",
                       path, sides.c_str());
        return RC_ERR_RANGE;
    }
    if (spec.tile_width != spec.tile_height || spec.tile_width <= 0 || spec.width != spec.tile_width ||
        spec.height != 6 * spec.tile_height) {
        status_message(err, errlen,
                       "%s: a DDS cube map whose faces are %dx%d, not square; give a cube map with square faces, as "
                       "Direct3D requires",
                       path, spec.tile_width, spec.tile_height);
        return RC_ERR_RANGE;
    }
    *w = spec.tile_width;
    *h = spec.tile_height;
    *faces = 6;
    return RC_OK;
}

rc_status decode(const char *path, const unsigned char *bytes, size_t len, image_dds_kind kind, int max_side,
                 image_dds *out, char *err, size_t errlen)
{
    // The DDS reader itself, so that a file of another format named .dds is refused rather than
    // read by whatever reader recognises it.
    auto in = OIIO::ImageInput::create("dds");
    if (!in) {
        status_message(err, errlen, "%s: this OpenImageIO has no DDS reader (%s); install libopenimageio2.4", path,
                       one_line(OIIO::geterror()).c_str());
        return RC_ERR_IO;
    }
    OIIO::Filesystem::IOMemReader mem(bytes, len);
    OIIO::ImageSpec spec;
    if (!in->set_ioproxy(&mem) || !in->open(path, spec)) {
        std::string why = one_line(in->geterror());
        bool unsupported = why.find("Unsupported") != std::string::npos;
        status_message(err, errlen, "%s: not a DDS file OpenImageIO %s reads (%s); %s", path, reflcheck_oiio_version(),
                       why.c_str(), unsupported ? dds_fix : "give a valid DDS file");
        return RC_ERR_PARSE;
    }
    int w = 0, h = 0, faces = 0;
    rc_status rc = check_kind(path, spec, kind, &w, &h, &faces, err, errlen);
    if (rc != RC_OK)
        return rc;
    if (w <= 0 || h <= 0 || w > max_side || h > max_side) {
        status_message(err, errlen, "%s: a %dx%d DDS image; give one of 1..%d texels a side", path, w, h, max_side);
        return RC_ERR_RANGE;
    }
    if (spec.nchannels < 3 || spec.nchannels > 4) {
        status_message(err, errlen,
                       "%s: %d channel%s (%s), not colour; give an RGB or RGBA DDS (BC4, BC5 and luminance hold "
                       "masks and normals, not colours)",
                       path, spec.nchannels, spec.nchannels == 1 ? "" : "s",
                       spec.get_string_attribute("compression", "uncompressed").c_str());
        return RC_ERR_RANGE;
    }
    // 8-bit data stays 8-bit so that the sRGB decode is the PNG/JPEG one, byte for byte; half and
    // float data (BC6H) is read as float.
    bool linear = spec.format.basetype == OIIO::TypeDesc::HALF || spec.format.basetype == OIIO::TypeDesc::FLOAT;
    if (!linear && spec.format.basetype != OIIO::TypeDesc::UINT8) {
        status_message(err, errlen, "%s: %s texels, neither 8-bit nor float; %s", path, spec.format.c_str(), dds_fix);
        return RC_ERR_PARSE;
    }
    size_t n = (size_t)w * (size_t)h * (size_t)faces;
    // The file must hold the 128-byte header and the top level of every face in the most compact
    // encoding OpenImageIO reads, BC1/BC4's 8 bytes a 4x4 block (every other takes more), before
    // anything is allocated. Decoded here, then converted to float RGBA by the caller: both must
    // fit the memory limit.
    double blocks = (double)((w + 3) / 4) * (double)((h + 3) / 4) * faces;
    rc_status budget =
        fileio_image_budget(path, "DDS", w, h, 128.0 + 8.0 * blocks, (long long)len,
                            (double)n * 4.0 * (sizeof(float) + (linear ? sizeof(float) : 1)), err, errlen);
    if (budget != RC_OK)
        return budget;
    void *px = linear ? std::malloc(n * 4 * sizeof(float)) : std::malloc(n * 4);
    if (px == NULL) {
        status_message(err, errlen, "%s: out of memory for %d face%s of %dx%d", path, faces, faces == 1 ? "" : "s", w,
                       h);
        return RC_ERR_NOMEM;
    }
    OIIO::TypeDesc type = linear ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    size_t texel = linear ? 4 * sizeof(float) : 4;
    // Alpha first, so that three channels read into four-channel strides leave it opaque.
    if (linear)
        for (size_t i = 0; i < n; i++)
            static_cast<float *>(px)[4 * i + 3] = 1.0f;
    else
        std::memset(px, 255, n * 4);
    // OpenImageIO 2.4 can return true from read_image and still record a short read (a truncated
    // file: "Read error: hit end of file"), so its error state is checked too.
    bool ok = in->read_image(0, 0, 0, spec.nchannels, type, px, (OIIO::stride_t)texel) && !in->has_error();
    if (!ok) {
        std::string e = one_line(in->geterror());
        std::free(px);
        status_message(err, errlen, "%s: truncated or corrupt DDS data (OpenImageIO: %s); give a complete DDS file",
                       path, e.c_str());
        return RC_ERR_PARSE;
    }
    *out = image_dds{};
    out->width = w;
    out->height = h;
    out->faces = faces;
    out->linear = linear;
    if (linear)
        out->rgbaf = static_cast<float *>(px);
    else
        out->rgba8 = static_cast<unsigned char *>(px);
    std::snprintf(out->format, sizeof out->format, "%s",
                  spec.get_string_attribute("compression", "uncompressed").c_str());
    return RC_OK;
}

} // namespace

extern "C" rc_status reflcheck_oiio_read(const char *path, image_dds_kind kind, long long max_bytes, int max_side,
                                    image_dds *out, char *err, size_t errlen)
{
    *out = image_dds{};
    unsigned char *bytes = NULL;
    size_t len = 0;
    rc_status rc = fileio_read_input(path, max_bytes, "a DDS image", &bytes, &len, err, errlen);
    if (rc != RC_OK)
        return rc;
    try {
        rc = decode(path, bytes, len, kind, max_side, out, err, errlen);
    } catch (const std::bad_alloc &) {
        status_message(err, errlen, "%s: out of memory decoding the DDS file", path);
        rc = RC_ERR_NOMEM;
    } catch (const std::exception &e) {
        status_message(err, errlen, "%s: OpenImageIO failed (%s); give a valid DDS file", path, e.what());
        rc = RC_ERR_PARSE;
    }
    std::free(bytes);
    return rc;
}

extern "C" void reflcheck_oiio_free(image_dds *d)
{
    std::free(d->rgba8);
    std::free(d->rgbaf);
    *d = image_dds{};
}

// The library as loaded at run time (a new libOpenImageIO may decode differently than the headers'
// version), as "major.minor.patch".
extern "C" const char *reflcheck_oiio_version(void)
{
    static const std::string v = [] {
        int n = OIIO::openimageio_version();
        return std::to_string(n / 10000) + "." + std::to_string(n / 100 % 100) + "." + std::to_string(n % 100);
    }();
    return v.c_str();
}
