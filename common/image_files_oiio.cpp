// The OpenImageIO module behind common/image_files.h: the only code that calls OpenImageIO.
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "common/detail/image_files_module.h"

namespace distile::image_files {

namespace fs = std::filesystem;

namespace {

OIIO::TypeDesc typeOf(PixelType type) {
    switch (type) {
        case PixelType::UInt8:
            return OIIO::TypeDesc::UINT8;
        case PixelType::UInt16:
            return OIIO::TypeDesc::UINT16;
        case PixelType::Half:
            return OIIO::TypeDesc::HALF;
        case PixelType::Float:
            break;
    }
    return OIIO::TypeDesc::FLOAT;
}

/// The stored type as distile names it; other integer types are read as UInt16 and other
/// floating-point types as Float (readers convert to float either way).
PixelType pixelTypeOf(OIIO::TypeDesc type) {
    if (type == OIIO::TypeDesc::UINT8) return PixelType::UInt8;
    if (type == OIIO::TypeDesc::HALF) return PixelType::Half;
    return type.is_floating_point() ? PixelType::Float : PixelType::UInt16;
}

Spec specOf(const OIIO::ImageSpec& from) {
    Spec spec;
    spec.width = from.width;
    spec.height = from.height;
    spec.depth = from.depth;
    spec.channels = from.nchannels;
    spec.deep = from.deep;
    spec.pixelType = pixelTypeOf(from.format);
    spec.channelNames = from.channelnames;
    for (const OIIO::ParamValue& entry : from.extra_attribs) {
        const std::string name = entry.name().string();
        if (entry.type() == OIIO::TypeDesc::STRING)
            spec.attributes.push_back({name, std::string(entry.get_string())});
        else if (entry.type() == OIIO::TypeDesc::INT)
            spec.attributes.push_back({name, entry.get_int()});
        else if (entry.type() == OIIO::TypeDesc::FLOAT)
            spec.attributes.push_back({name, entry.get_float()});
    }
    return spec;
}

class OiioInput final : public Input {
  public:
    explicit OiioInput(std::unique_ptr<OIIO::ImageInput> input)
        : input_(std::move(input)), spec_(specOf(input_->spec())) {}
    const Spec& spec() const override { return spec_; }
    std::string readFloats(int channels, std::span<float> pixels) override {
        if (pixels.size() <
            std::size_t(spec_.width) * std::size_t(spec_.height) * std::size_t(channels))
            return "the pixel buffer is too small";
        if (input_->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, pixels.data())) return {};
        return firstLine(input_->geterror());
    }

  private:
    std::unique_ptr<OIIO::ImageInput> input_;
    Spec spec_;
};

std::unique_ptr<Input> openFile(const fs::path& file, std::string& error) {
    auto input = OIIO::ImageInput::create(file.string());
    if (!input) {
        error = OIIO::geterror();
        if (error.empty()) error = "no image format is known by the extension";
        return nullptr;
    }
    OIIO::ImageSpec spec;
    if (!input->open(file.string(), spec)) {
        error = input->geterror();
        return nullptr;
    }
    return std::make_unique<OiioInput>(std::move(input));
}

std::string writeFile(const fs::path& file, const Spec& spec, PixelType given, const void* pixels) {
    OIIO::ImageSpec to(spec.width, spec.height, spec.channels, typeOf(spec.pixelType));
    if (!spec.channelNames.empty()) to.channelnames = spec.channelNames;
    // OpenImageIO stamps EXR and TIFF files with the time of writing unless DateTime is given;
    // empty, none is written, so the same pixels give the same file (an attribute may set one).
    to.attribute("DateTime", "");
    for (const Attribute& attribute : spec.attributes) {
        std::visit([&](const auto& value) { to.attribute(attribute.name, value); },
                   attribute.value);
    }
    auto output = OIIO::ImageOutput::create(file.string());
    if (!output) return "OpenImageIO has no writer for it (" + firstLine(OIIO::geterror()) + ")";
    if (!output->open(file.string(), to) || !output->write_image(typeOf(given), pixels) ||
        !output->close())
        return "writing failed (" + firstLine(output->geterror()) + ")";
    return {};
}

bool drawTextInto(std::span<float> rgb, int width, int height, int x, int baseline,
                  const std::string& text, int fontPixels, const std::string& font,
                  const float (&color)[3]) {
    if (rgb.size() < std::size_t(width) * std::size_t(height) * 3) return false;
    OIIO::ImageBuf picture(OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::FLOAT), rgb.data());
    return OIIO::ImageBufAlgo::render_text(picture, x, baseline, text, fontPixels, font, color);
}

constexpr detail::ModuleFunctions kFunctions{openFile, writeFile, drawTextInto};

}  // namespace

}  // namespace distile::image_files

extern "C" __attribute__((visibility("default"))) const void* distile_image_files_module() {
    return &distile::image_files::kFunctions;
}
