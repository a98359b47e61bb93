// exr_dump IN.exr OUT.bin: what OpenEXR itself reads from a file, for the node tests to hold
// three.js's EXRLoader against: prints a JSON line (size, channel names in file order, the
// lightlink.* int and string attributes) and writes the pixels to OUT.bin as little-endian
// float32, channel-interleaved in that order, row 0 (the file's first row) first.
// OpenEXR is used directly, not lightlink's reader, so the check is reader against reader.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <nlohmann/json.hpp>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s IN.exr OUT.bin\n", argv[0]);
    return 2;
  }
  try {
    Imf::InputFile file(argv[1]);
    const Imf::Header& h = file.header();
    const Imath::Box2i dw = h.dataWindow();
    const int w = dw.max.x - dw.min.x + 1, hgt = dw.max.y - dw.min.y + 1;
    nlohmann::ordered_json j;
    j["width"] = w;
    j["height"] = hgt;
    std::vector<std::string> names;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) names.push_back(it.name());
    j["channels"] = names;
    j["half"] = !names.empty() && h.channels().findChannel(names[0].c_str())->type == Imf::HALF;
    nlohmann::ordered_json attrs = nlohmann::ordered_json::object();
    for (auto it = h.begin(); it != h.end(); ++it) {
      const std::string name = it.name();
      if (name.rfind("lightlink.", 0) != 0) continue;
      if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&it.attribute())) attrs[name] = i->value();
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) attrs[name] = s->value();
    }
    j["attributes"] = attrs;
    const std::size_t nc = names.size(), texels = std::size_t(w) * std::size_t(hgt);
    std::vector<float> px(texels * nc);
    Imf::FrameBuffer fb;
    const std::size_t xs = sizeof(float) * nc;
    const std::ptrdiff_t origin = std::ptrdiff_t(dw.min.x) + std::ptrdiff_t(dw.min.y) * w;
    for (std::size_t c = 0; c < nc; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data() + c) - origin * std::ptrdiff_t(xs),
                                     xs, xs * std::size_t(w)));
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    std::ofstream out(argv[2], std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(px.data()), std::streamsize(px.size() * sizeof(float)));
    if (!out) {
      std::fprintf(stderr, "cannot write %s\n", argv[2]);
      return 1;
    }
    std::printf("%s\n", j.dump().c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[1], e.what());
    return 1;
  }
  return 0;
}
