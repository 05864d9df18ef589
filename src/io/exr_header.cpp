// An output part's OpenEXR header from its spec (write_layout.h): windows, channels, compression,
// tiles and levels, and every carried attribute under OpenEXR's name and type. The names follow
// OpenImageIO's reader in reverse (DateTime -> capDate, FNumber -> aperture, ...), so a file
// read by posthaste and written again keeps its header; OpenImageIO's own directives (oiio:*,
// openexr:*, textureformat) become header fields, not attributes.

#include <OpenEXR/ImfBoxAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFloatVectorAttribute.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfKeyCodeAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOpaqueAttribute.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfRationalAttribute.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfStringVectorAttribute.h>
#include <OpenEXR/ImfTimeCodeAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>
#include <OpenImageIO/strutil.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "core/error.h"
#include "io/io_detail.h"
#include "io/write_layout.h"

namespace posthaste::io_detail {

namespace {

using OIIO::TypeDesc;
using OIIO::Strutil::iequals;
using OIIO::Strutil::istarts_with;

/// OpenImageIO's standard names and their OpenEXR names and types (an empty OpenEXR name: not
/// an attribute of the file, e.g. what the header's own fields hold).
struct Rename {
    const char *oiio;
    const char *exr;
    TypeDesc type;
};

const Rename kRenames[] = {
    {"worldtocamera", "worldToCamera", OIIO::TypeMatrix44},
    {"worldtoNDC", "worldToNDC", OIIO::TypeMatrix44},
    {"worldtoscreen", "worldToScreen", OIIO::TypeMatrix44},
    {"DateTime", "capDate", OIIO::TypeString},
    {"ImageDescription", "comments", OIIO::TypeString},
    {"description", "comments", OIIO::TypeString},
    {"Copyright", "owner", OIIO::TypeString},
    {"PixelAspectRatio", "pixelAspectRatio", OIIO::TypeFloat},
    {"XResolution", "xDensity", OIIO::TypeFloat},
    {"ExposureTime", "expTime", OIIO::TypeFloat},
    {"FNumber", "aperture", OIIO::TypeFloat},
    {"oiio:subimagename", "name", OIIO::TypeString},
    {"smpte:TimeCode", "timeCode", OIIO::TypeTimeCode},
    {"smpte:KeyCode", "keyCode", OIIO::TypeKeyCode},
    {"YResolution", "", TypeDesc::UNKNOWN},
    {"ResolutionUnit", "", TypeDesc::UNKNOWN},  // OpenEXR's xDensity is per inch
    {"planarconfig", "", TypeDesc::UNKNOWN},
    {"type", "", TypeDesc::UNKNOWN},
    {"tiles", "", TypeDesc::UNKNOWN},
    {"chunkCount", "", TypeDesc::UNKNOWN},
    {"maxSamplesPerPixel", "", TypeDesc::UNKNOWN},
    {"textureformat", "", TypeDesc::UNKNOWN},
    {"compression", "", TypeDesc::UNKNOWN},
};

/// Insert one carried attribute under its OpenEXR name and type; false when it has no place in
/// an OpenEXR header (a directive, a type OpenEXR cannot hold).
bool put_attribute(const std::string &name, TypeDesc type, const void *data, Imf::Header &h)
{
    if (name.empty() || !data) {
        return false;
    }
    std::string xname = name;
    TypeDesc want = TypeDesc::UNKNOWN;
    for (const Rename &r : kRenames) {
        if (iequals(name, r.oiio) || (r.exr[0] != '\0' && iequals(name, r.exr))) {
            xname = r.exr;
            want = r.type;
            break;
        }
    }
    if (xname.empty() || istarts_with(xname, "openexr:") || istarts_with(xname, "ICCProfile:")) {
        return false;
    }
    if (istarts_with(xname, "oiio:") && !iequals(xname, "oiio:ConstantColor") &&
        !iequals(xname, "oiio:AverageColor") && !iequals(xname, "oiio:SHA-1")) {
        return false;
    }
    // Another format's own metadata ("tiff:...", "jpeg:...") stays with that format.
    if (const auto colon = xname.find(':'); colon != std::string::npos) {
        const std::string prefix = OIIO::Strutil::lower(xname.substr(0, colon));
        if (prefix != "openexr" && OIIO::is_imageio_format_name(prefix)) {
            return false;
        }
    }
    float fvalue = 0.0f;
    if (want == OIIO::TypeFloat && type == OIIO::TypeInt) {
        fvalue = float(*static_cast<const int *>(data));
        data = &fvalue;
        type = OIIO::TypeFloat;
    } else if (want == OIIO::TypeMatrix44 && type == TypeDesc(TypeDesc::FLOAT, 16)) {
        type = OIIO::TypeMatrix44;
    }
    if (want != TypeDesc::UNKNOWN && !want.equivalent(type)) {
        return false;
    }
    const char *n = xname.c_str();
    const auto *i = static_cast<const int *>(data);
    const auto *f = static_cast<const float *>(data);
    const auto *d = static_cast<const double *>(data);
    const auto *s = static_cast<const char *const *>(data);
    const TypeDesc::BASETYPE base = TypeDesc::BASETYPE(type.basetype);
    const bool ints = base == TypeDesc::INT || base == TypeDesc::UINT;
    if (type.arraylen == 0) {
        if (type.aggregate == TypeDesc::SCALAR) {
            switch (base) {
                case TypeDesc::INT:
                case TypeDesc::UINT:
                    h.insert(n, Imf::IntAttribute(*i));
                    return true;
                case TypeDesc::INT16:
                    h.insert(n, Imf::IntAttribute(*static_cast<const short *>(data)));
                    return true;
                case TypeDesc::UINT16:
                    h.insert(n, Imf::IntAttribute(*static_cast<const unsigned short *>(data)));
                    return true;
                case TypeDesc::FLOAT:
                    h.insert(n, Imf::FloatAttribute(*f));
                    return true;
                case TypeDesc::HALF:
                    h.insert(n, Imf::FloatAttribute(float(*static_cast<const half *>(data))));
                    return true;
                case TypeDesc::DOUBLE:
                    h.insert(n, Imf::DoubleAttribute(*d));
                    return true;
                case TypeDesc::STRING:
                    if (!*s) {
                        return false;
                    }
                    h.insert(n, Imf::StringAttribute(*s));
                    return true;
                default:
                    return false;
            }
        }
        if (type.aggregate == TypeDesc::VEC2) {
            if (ints && type.vecsemantics == TypeDesc::RATIONAL) {
                h.insert(n,
                         Imf::RationalAttribute(
                             Imf::Rational(i[0], static_cast<const unsigned *>(data)[1])));
                return true;
            }
            if (ints) {
                h.insert(n, Imf::V2iAttribute(Imath::V2i(i[0], i[1])));
            } else if (base == TypeDesc::FLOAT) {
                h.insert(n, Imf::V2fAttribute(Imath::V2f(f[0], f[1])));
            } else if (base == TypeDesc::DOUBLE) {
                h.insert(n, Imf::V2dAttribute(Imath::V2d(d[0], d[1])));
            } else if (base == TypeDesc::STRING) {
                h.insert(n, Imf::StringVectorAttribute(Imf::StringVector{s[0], s[1]}));
            } else {
                return false;
            }
            return true;
        }
        if (type.aggregate == TypeDesc::VEC3) {
            if (ints) {
                h.insert(n, Imf::V3iAttribute(Imath::V3i(i[0], i[1], i[2])));
            } else if (base == TypeDesc::FLOAT) {
                h.insert(n, Imf::V3fAttribute(Imath::V3f(f[0], f[1], f[2])));
            } else if (base == TypeDesc::DOUBLE) {
                h.insert(n, Imf::V3dAttribute(Imath::V3d(d[0], d[1], d[2])));
            } else if (base == TypeDesc::STRING) {
                h.insert(n, Imf::StringVectorAttribute(Imf::StringVector{s[0], s[1], s[2]}));
            } else {
                return false;
            }
            return true;
        }
    }
    if (type.arraylen < 0) {
        return false;
    }
    if (type == OIIO::TypeTimeCode) {
        Imf::TimeCode tc;
        tc.setTimeAndFlags(static_cast<const unsigned *>(data)[0]);
        tc.setUserData(static_cast<const unsigned *>(data)[1]);
        h.insert(n, Imf::TimeCodeAttribute(tc));
        return true;
    }
    if (type == OIIO::TypeKeyCode) {
        h.insert(n, Imf::KeyCodeAttribute(Imf::KeyCode(i[0], i[1], i[2], i[3], i[4], i[5], i[6])));
        return true;
    }
    const std::size_t values = type.basevalues();
    if (type.arraylen == 2 && type.aggregate == TypeDesc::VEC2) {  // two corners: a box
        if (ints) {
            h.insert(
                n,
                Imf::Box2iAttribute(Imath::Box2i(Imath::V2i(i[0], i[1]), Imath::V2i(i[2], i[3]))));
            return true;
        }
        if (base == TypeDesc::FLOAT) {
            h.insert(
                n,
                Imf::Box2fAttribute(Imath::Box2f(Imath::V2f(f[0], f[1]), Imath::V2f(f[2], f[3]))));
            return true;
        }
    }
    if (type.aggregate == TypeDesc::SCALAR || type.aggregate == TypeDesc::MATRIX33 ||
        type.aggregate == TypeDesc::MATRIX44) {
        if (values == 2 && ints && type.aggregate == TypeDesc::SCALAR) {
            h.insert(n, Imf::V2iAttribute(Imath::V2i(i[0], i[1])));
            return true;
        }
        if (values == 3 && ints && type.aggregate == TypeDesc::SCALAR) {
            h.insert(n, Imf::V3iAttribute(Imath::V3i(i[0], i[1], i[2])));
            return true;
        }
        // A plain array of floats is OpenEXR's floatvector (what OpenImageIO reads one as),
        // whatever its length: 2, 3 or 16 of them went out as v2f, v3f or m44f.
        if (base == TypeDesc::FLOAT && type.aggregate == TypeDesc::SCALAR &&
            !(values == 8 && iequals(xname, "chromaticities"))) {
            h.insert(n, Imf::FloatVectorAttribute(Imf::FloatVector(f, f + values)));
            return true;
        }
        if (base == TypeDesc::FLOAT || base == TypeDesc::DOUBLE) {
            const bool dbl = base == TypeDesc::DOUBLE;
            if (values == 2 && type.aggregate == TypeDesc::SCALAR) {
                dbl ? h.insert(n, Imf::V2dAttribute(Imath::V2d(d[0], d[1])))
                    : h.insert(n, Imf::V2fAttribute(Imath::V2f(f[0], f[1])));
                return true;
            }
            if (values == 3 && type.aggregate == TypeDesc::SCALAR) {
                dbl ? h.insert(n, Imf::V3dAttribute(Imath::V3d(d[0], d[1], d[2])))
                    : h.insert(n, Imf::V3fAttribute(Imath::V3f(f[0], f[1], f[2])));
                return true;
            }
            if (values == 9) {
                dbl ? h.insert(
                          n,
                          Imf::M33dAttribute(Imath::M33d(reinterpret_cast<const double(*)[3]>(d))))
                    : h.insert(
                          n,
                          Imf::M33fAttribute(Imath::M33f(reinterpret_cast<const float(*)[3]>(f))));
                return true;
            }
            if (values == 16) {
                dbl ? h.insert(
                          n,
                          Imf::M44dAttribute(Imath::M44d(reinterpret_cast<const double(*)[4]>(d))))
                    : h.insert(
                          n,
                          Imf::M44fAttribute(Imath::M44f(reinterpret_cast<const float(*)[4]>(f))));
                return true;
            }
        }
    }
    if (base == TypeDesc::FLOAT && values == 8 && iequals(xname, "chromaticities")) {
        h.insert("chromaticities",
                 Imf::ChromaticitiesAttribute(Imf::Chromaticities(Imath::V2f(f[0], f[1]),
                                                                  Imath::V2f(f[2], f[3]),
                                                                  Imath::V2f(f[4], f[5]),
                                                                  Imath::V2f(f[6], f[7]))));
        return true;
    }
    if (base == TypeDesc::STRING) {
        Imf::StringVector v;
        for (std::size_t k = 0; k < values; ++k) {
            v.emplace_back(s[k] ? s[k] : "");
        }
        h.insert(n, Imf::StringVectorAttribute(v));
        return true;
    }
    if (base == TypeDesc::FLOAT) {
        h.insert(n, Imf::FloatVectorAttribute(Imf::FloatVector(f, f + values)));
        return true;
    }
    return false;
}

/// Attributes the writer sets from the layout it writes (or OpenEXR from the file): never
/// carried from the source's header as they were.
bool is_layout_attribute(const std::string &name)
{
    static const char *const kNames[] = {"channels",
                                         "compression",
                                         "dataWindow",
                                         "displayWindow",
                                         "lineOrder",
                                         "tiles",
                                         "type",
                                         "name",
                                         "view",
                                         "multiView",
                                         "chunkCount",
                                         "version",
                                         "maxSamplesPerPixel",
                                         "dwaCompressionLevel",
                                         "envmap"};
    for (const char *n : kNames) {
        if (name == n) {
            return true;
        }
    }
    return false;
}

/// Attributes that summarise a part's pixels (OpenImageIO's; its texture system trusts
/// ConstantColor): left out once a node changed the pixels, as previews are.
const std::string kPixelSummaries[] = {"oiio:ConstantColor", "oiio:AverageColor", "oiio:SHA-1"};

/// An attribute's type name and value as OpenEXR writes them.
std::string serialized(const Imf::Attribute &a)
{
    Imf::StdOSStream os;
    a.writeValueTo(os, 2);
    return std::string(a.typeName()) + '\0' + os.str();
}

/// The attribute `raw` holds, as OpenEXR would read it from the file (an opaque attribute for a
/// type it does not know); null when its bytes do not parse.
std::unique_ptr<Imf::Attribute> parse_attribute(const HeaderAttribute &raw)
{
    try {
        std::unique_ptr<Imf::Attribute> a(Imf::Attribute::knownType(raw.type.c_str())
                                              ? Imf::Attribute::newAttribute(raw.type.c_str())
                                              : new Imf::OpaqueAttribute(raw.type.c_str()));
        Imf::StdISStream is;
        is.str(std::string(raw.value.begin(), raw.value.end()));
        a->readValueFrom(is, int(raw.value.size()), 2);
        return a;
    } catch (const std::exception &) {
        return nullptr;
    }
}

/// The OpenEXR attributes put_attribute makes of one OpenImageIO attribute (its own name, or
/// the standard name it stands for: FNumber -> aperture).
std::vector<std::string> exr_names_of(const OIIO::ParamValue &p)
{
    Imf::Header scratch;
    static const std::vector<std::string> defaults = [] {
        std::vector<std::string> names;
        const Imf::Header empty;
        for (auto it = empty.begin(); it != empty.end(); ++it) {
            names.emplace_back(it.name());
        }
        return names;
    }();
    try {
        put_attribute(p.name().string(), p.type(), p.data(), scratch);
    } catch (const std::exception &) {
    }
    std::vector<std::string> names;
    for (auto it = scratch.begin(); it != scratch.end(); ++it) {
        if (std::find(defaults.begin(), defaults.end(), it.name()) == defaults.end() ||
            p.name().string() == it.name()) {
            names.emplace_back(it.name());
        }
    }
    return names;
}

/// `h` with the source part's attributes put back as the file had them (HeaderAttribute).
/// One OpenImageIO showed under its own name comes back when the part's spec still holds that
/// value (the graph left it alone), in place of what put_attribute made of it (an alias such as
/// aperture for a studio's own FNumber is not added beside it); one it showed under another
/// name comes back where `h` holds the value the source's spec gives; one it never showed comes
/// back as it was, except a preview once the part's pixels changed (`stale`). What the graph
/// changed, added or removed stays as `h` has it.
void restore_source_attributes(const SourcePart &source,
                               const OIIO::ImageSpec &spec,
                               bool stale,
                               Imf::Header &h)
{
    Imf::Header as_read;  // what the source's spec, unchanged, gives
    for (const OIIO::ParamValue &p : source.spec.extra_attribs) {
        try {
            put_attribute(p.name().string(), p.type(), p.data(), as_read);
        } catch (const std::exception &) {
        }
    }
    auto raw_named = [&](const std::string &name) {
        return std::any_of(source.attributes.begin(),
                           source.attributes.end(),
                           [&](const HeaderAttribute &a) { return a.name == name; });
    };
    for (const HeaderAttribute &raw : source.attributes) {
        if (is_layout_attribute(raw.name) ||
            (stale &&
             (raw.type == "preview" ||
              std::find(std::begin(kPixelSummaries), std::end(kPixelSummaries), raw.name) !=
                  std::end(kPixelSummaries)))) {
            continue;
        }
        if (const OIIO::ParamValue *was = source.spec.find_attribute(raw.name)) {
            const OIIO::ParamValue *now = spec.find_attribute(raw.name);
            if (!now || now->type() != was->type() || now->nvalues() != was->nvalues() ||
                std::memcmp(now->data(), was->data(), was->datasize()) != 0) {
                continue;  // changed or removed by the graph
            }
            std::unique_ptr<Imf::Attribute> original = parse_attribute(raw);
            if (!original) {
                continue;
            }
            for (const std::string &alias : exr_names_of(*was)) {
                if (alias != raw.name && !raw_named(alias) && h.find(alias) != h.end()) {
                    h.erase(alias);
                }
            }
            if (h.find(raw.name) != h.end()) {
                h.erase(raw.name);
            }
            h.insert(raw.name, *original);
            continue;
        }
        const auto now = h.find(raw.name);
        const auto was = as_read.find(raw.name);
        const bool in_now = now != h.end(), in_was = was != as_read.end();
        if (in_now != in_was ||
            (in_now && serialized(now.attribute()) != serialized(was.attribute()))) {
            continue;
        }
        std::unique_ptr<Imf::Attribute> original = parse_attribute(raw);
        if (!original) {
            continue;
        }
        if (in_now) {
            h.erase(raw.name);
        }
        h.insert(raw.name, *original);
    }
}

}  // namespace

Imf::PixelType exr_pixel_type(OIIO::TypeDesc t)
{
    switch (t.basetype) {
        case TypeDesc::UINT:
            return Imf::UINT;
        case TypeDesc::FLOAT:
        case TypeDesc::DOUBLE:
            return Imf::FLOAT;
        default:
            return Imf::HALF;
    }
}

Imf::Header exr_header(const OutPart &part, int index, int parts, const std::string &path)
{
    const OIIO::ImageSpec &spec = part.spec;
    const Rect &dw = part.data_window;
    Imf::Header h(Imath::Box2i(Imath::V2i(spec.full_x, spec.full_y),
                               Imath::V2i(spec.full_x + spec.full_width - 1,
                                          spec.full_y + spec.full_height - 1)),
                  Imath::Box2i(Imath::V2i(dw.x0, dw.y0), Imath::V2i(dw.x1 - 1, dw.y1 - 1)));
    for (const OutChannel &c : part.channels) {
        if (h.channels().findChannel(c.name)) {
            throw_runtime(path, ": part ", index, " names channel \"", c.name, "\" twice");
        }
        h.channels().insert(c.name, Imf::Channel(exr_pixel_type(c.type)));
    }

    // Compression and its level: "zip:6", "dwaa:45"; zip at level 4 unless one is given (what
    // OpenImageIO chose, for the same bytes as before).
    const std::string compression = spec.get_string_attribute("compression", "zip");
    const auto colon = compression.find(':');
    std::string codec = compression.substr(0, colon);
    const double level =
        colon == std::string::npos ? -1.0 : std::strtod(compression.c_str() + colon + 1, nullptr);
    if (spec.tile_width > 0 && part.channels.size() == 1 && istarts_with(codec, "dwa") &&
        ((spec.tile_width < 16 && spec.tile_height < 16) ||
         (spec.tile_width & (spec.tile_width - 1)) ||
         (spec.tile_height & (spec.tile_height - 1)))) {
        codec = "zip";  // OpenEXR's DWA fails on one-channel tiles of such sizes
    }
    const int id = exr_compression_id(codec);  // validated by check_compression; zip else
    h.compression() = id >= 0 ? Imf::Compression(id) : Imf::ZIP_COMPRESSION;
    if (istarts_with(codec, "zip")) {
        h.zipCompressionLevel() = level >= 1 && level <= 9 ? int(level) : 4;
    }
    if (istarts_with(codec, "dwa") && level > 0) {
        h.dwaCompressionLevel() = float(level);
        h.insert("dwaCompressionLevel", Imf::FloatAttribute(float(level)));
    }

    const std::string order = spec.get_string_attribute("openexr:lineOrder", "increasingY");
    h.lineOrder() = iequals(order, "decreasingY")                      ? Imf::DECREASING_Y
                    : iequals(order, "randomY") && spec.tile_width > 0 ? Imf::RANDOM_Y
                                                                       : Imf::INCREASING_Y;

    const std::string tex = spec.get_string_attribute("textureformat");
    if (iequals(tex, "CubeFace Environment")) {
        h.insert("envmap", Imf::EnvmapAttribute(Imf::ENVMAP_CUBE));
    } else if (iequals(tex, "LatLong Environment")) {
        h.insert("envmap", Imf::EnvmapAttribute(Imf::ENVMAP_LATLONG));
    }
    if (spec.tile_width > 0) {
        const bool levels = part.copy_levels || part.make_levels;
        const int rounding = spec.get_int_attribute("openexr:roundingmode", Imf::ROUND_DOWN);
        h.setTileDescription(
            Imf::TileDescription(spec.tile_width,
                                 spec.tile_height,
                                 !levels                              ? Imf::ONE_LEVEL
                                 : part.source && part.source->ripmap ? Imf::RIPMAP_LEVELS
                                                                      : Imf::MIPMAP_LEVELS,
                                 rounding == Imf::ROUND_UP ? Imf::ROUND_UP : Imf::ROUND_DOWN));
    }

    const float aspect = spec.get_float_attribute("PixelAspectRatio", 0.0f);
    const float xdensity = spec.get_float_attribute("XResolution", 0.0f);
    const float ydensity = spec.get_float_attribute("YResolution", 0.0f);
    for (const OIIO::ParamValue &p : spec.extra_attribs) {
        const std::string name = p.name().string();
        if (iequals(name, "XResolution") && xdensity != 0.0f && ydensity != 0.0f &&
            spec.get_string_attribute("ResolutionUnit") == "cm") {
            h.insert("xDensity", Imf::FloatAttribute(xdensity / 2.54f));  // OpenEXR's is per inch
            continue;
        }
        try {
            put_attribute(name, p.type(), p.data(), h);
        } catch (const std::exception &) {
            // A value OpenEXR refuses (a key code out of its ranges): not carried, as before.
        }
    }
    if (aspect == 0.0f && xdensity != 0.0f && ydensity != 0.0f) {
        h.pixelAspectRatio() = xdensity / ydensity;
    }
    // Attributes that summarise the pixels are stale once a node changed them.
    const bool stale = part.cut || std::any_of(part.channels.begin(),
                                               part.channels.end(),
                                               [](const OutChannel &c) { return !c.untouched; });
    if (stale) {
        for (const std::string &name : kPixelSummaries) {
            if (h.find(name) != h.end()) {
                h.erase(name);
            }
        }
    }
    if (part.header_source) {
        restore_source_attributes(*part.header_source, spec, stale, h);
    }
    if (parts > 1 && !h.hasName()) {
        char name[32];
        std::snprintf(name, sizeof(name), "subimage%02d", index);
        h.setName(name);
    }
    h.setType(spec.tile_width > 0 ? Imf::TILEDIMAGE : Imf::SCANLINEIMAGE);  // MultiPartOutputFile's
    return h;
}

}  // namespace posthaste::io_detail
