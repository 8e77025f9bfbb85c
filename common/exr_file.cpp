#include "common/detail/exr_file.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <mutex>
#include <string_view>
#include <utility>
#include <vector>

namespace distile::image_files::detail {

namespace {

/// OpenImageIO's names of OpenEXR's compressions.
constexpr std::array<std::pair<std::string_view, Imf::Compression>, 10> kCompressions = {{
    {"none", Imf::NO_COMPRESSION},
    {"rle", Imf::RLE_COMPRESSION},
    {"zips", Imf::ZIPS_COMPRESSION},
    {"zip", Imf::ZIP_COMPRESSION},
    {"piz", Imf::PIZ_COMPRESSION},
    {"pxr24", Imf::PXR24_COMPRESSION},
    {"b44", Imf::B44_COMPRESSION},
    {"b44a", Imf::B44A_COMPRESSION},
    {"dwaa", Imf::DWAA_COMPRESSION},
    {"dwab", Imf::DWAB_COMPRESSION},
}};

std::string channelName(const Spec& spec, int channel) {
    if (!spec.channelNames.empty()) return spec.channelNames[std::size_t(channel)];
    return spec.channels == 1 ? "Y" : std::string(1, "RGBA"[channel]);
}

}  // namespace

void useExrThreads() {
    static std::once_flag once;
    std::call_once(once, [] {
        const int threads =
            int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
        if (threads > 1) Imf::setGlobalThreadCount(threads);
    });
}

std::string writeExr(const std::filesystem::path& file, const Spec& spec, PixelType given,
                     const void* pixels) {
    const bool namesGiven = !spec.channelNames.empty();
    if (given != PixelType::Float ||
        (spec.pixelType != PixelType::Float && spec.pixelType != PixelType::Half)) {
        return "an OpenEXR file is written from floats, stored as half or float";
    }
    if (namesGiven ? spec.channelNames.size() != std::size_t(spec.channels)
                   : !(spec.channels == 1 || spec.channels == 3 || spec.channels == 4)) {
        return std::to_string(spec.channels) +
               " channels without a name each (1, 3 or 4 have "
               "default names)";
    }
    try {
        Imf::Header header(spec.width, spec.height);
        header.compression() = Imf::ZIP_COMPRESSION;
        for (const Attribute& attribute : spec.attributes) {
            if (attribute.name.starts_with("oiio:")) continue;
            const auto* text = std::get_if<std::string>(&attribute.value);
            if (attribute.name == "compression" && text) {
                const auto* known =
                    std::find_if(kCompressions.begin(), kCompressions.end(),
                                 [&](const auto& named) { return named.first == *text; });
                if (known == kCompressions.end())
                    return "compression '" + *text + "' is not one OpenEXR has";
                header.compression() = known->second;
            } else if (text) {
                header.insert(attribute.name, Imf::StringAttribute(*text));
            } else if (const auto* number = std::get_if<float>(&attribute.value)) {
                header.insert(attribute.name, Imf::FloatAttribute(*number));
            } else {
                header.insert(attribute.name, Imf::IntAttribute(std::get<int>(attribute.value)));
            }
        }
        const std::size_t values =
            std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(spec.channels);
        const auto* floats = static_cast<const float*>(pixels);
        // OpenEXR converts pixel types when reading only: half files are written from halves.
        std::vector<Imath::half> halves;
        if (spec.pixelType == PixelType::Half) halves.assign(floats, floats + values);
        const Imf::PixelType stored = spec.pixelType == PixelType::Half ? Imf::HALF : Imf::FLOAT;
        const std::size_t valueBytes = stored == Imf::HALF ? sizeof(Imath::half) : sizeof(float);
        char* base = stored == Imf::HALF ? reinterpret_cast<char*>(halves.data())
                                         : const_cast<char*>(reinterpret_cast<const char*>(floats));
        const std::size_t pixelBytes = valueBytes * std::size_t(spec.channels);
        Imf::FrameBuffer frame;
        for (int channel = 0; channel < spec.channels; ++channel) {
            const std::string name = channelName(spec, channel);
            header.channels().insert(name, Imf::Channel(stored));
            frame.insert(name, Imf::Slice(stored, base + valueBytes * std::size_t(channel),
                                          pixelBytes, pixelBytes * std::size_t(spec.width)));
        }
        useExrThreads();
        Imf::OutputFile output(file.c_str(), header);
        output.setFrameBuffer(frame);
        output.writePixels(spec.height);
    } catch (const std::exception& error) {
        return "writing failed (" + firstLine(error.what(), "unknown OpenEXR error") + ")";
    }
    return "";
}

}  // namespace distile::image_files::detail
