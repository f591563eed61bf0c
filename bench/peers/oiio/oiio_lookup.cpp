// OpenImageIO's TextureSystem on quadtex's footprint dump (see
// docs/footprints.md): one texture() call per textured pixel with the dumped
// s, t and derivatives, timed on one thread with a warm cache (median of
// several passes), for several filter settings. Writes one EXR per setting
// and a TSV line per setting to stdout:
//   method  ns_per_lookup  tx_bytes  file
//
// Usage: oiio_lookup DIR [PASSES]
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/texture.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

using namespace OIIO;

struct Record {
    uint32_t texture;
    float f[14];  // s t dsdx dtdx dsdy dtdy, quad (8)
};

struct Dump {
    uint32_t width = 0, height = 0;
    std::vector<std::pair<uint8_t, std::string>> textures;  // wrap, file
    std::vector<Record> records;
};

static bool read_dump(const std::string& path, Dump& d)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    char magic[8];
    in.read(magic, 8);
    if (!in || std::memcmp(magic, "QTXFP001", 8) != 0) return false;
    uint32_t count = 0;
    in.read((char*)&d.width, 4);
    in.read((char*)&d.height, 4);
    in.read((char*)&count, 4);
    for (uint32_t i = 0; i < count && in; ++i) {
        uint8_t wrap = 0;
        uint32_t len = 0;
        in.read((char*)&wrap, 1);
        in.read((char*)&len, 4);
        std::string name(len, '\0');
        in.read(name.data(), len);
        d.textures.emplace_back(wrap, name);
    }
    size_t n = size_t(d.width) * d.height;
    d.records.resize(n);
    for (size_t i = 0; i < n && in; ++i) {
        in.read((char*)&d.records[i].texture, 4);
        in.read((char*)d.records[i].f, 4 * 14);
    }
    return bool(in);
}

struct Setting {
    const char* name;
    TextureOpt::MipMode mip;
    TextureOpt::InterpMode interp;
    int aniso;
};

int main(int argc, char** argv)
{
    if (argc < 2) {
        std::cerr << "usage: oiio_lookup DIR [PASSES]\n";
        return 2;
    }
    std::string dir = argv[1];
    int passes = argc > 2 ? std::max(1, std::atoi(argv[2])) : 5;
    Dump dump;
    if (!read_dump(dir + "/footprints.bin", dump)) {
        std::cerr << "Error: " << dir << "/footprints.bin: not a readable footprint dump\n";
        return 1;
    }
    // Make .tx files: tiled, box-filtered mip levels, wrap as the scene says.
    std::vector<ustring> tx;
    uint64_t tx_bytes = 0;
    for (size_t i = 0; i < dump.textures.size(); ++i) {
        const char* wrap = dump.textures[i].first == 0   ? "periodic"
                           : dump.textures[i].first == 1 ? "clamp"
                                                         : "black";
        std::string src = dir + "/" + dump.textures[i].second;
        std::string out = dir + "/texture-" + std::to_string(i) + ".tx";
        ImageSpec config;
        config.attribute("maketx:filtername", "box");
        config.attribute("wrapmodes", std::string(wrap) + "," + wrap);
        config.attribute("maketx:highlightcomp", 0);
        if (!ImageBufAlgo::make_texture(ImageBufAlgo::MakeTxTexture, src, out, config)) {
            std::cerr << "Error: make_texture " << src << ": " << OIIO::geterror() << "\n";
            return 1;
        }
        tx.emplace_back(out);
        tx_bytes += std::filesystem::file_size(out);
    }
    TextureSystem* ts = TextureSystem::create(false);
    ts->attribute("max_memory_MB", 2048.0f);
    TextureSystem::Perthread* thread = ts->get_perthread_info();
    std::vector<TextureSystem::TextureHandle*> handles;
    for (auto& t : tx) handles.push_back(ts->get_texture_handle(t, thread));

    const Setting settings[] = {
        {"OIIO aniso 16 bilinear", TextureOpt::MipModeAniso, TextureOpt::InterpBilinear, 16},
        {"OIIO aniso 32 smartbicubic", TextureOpt::MipModeAniso, TextureOpt::InterpSmartBicubic, 32},
        {"OIIO aniso 32 bilinear", TextureOpt::MipModeAniso, TextureOpt::InterpBilinear, 32},
        {"OIIO trilinear bilinear", TextureOpt::MipModeTrilinear, TextureOpt::InterpBilinear, 1},
    };
    std::cout << "method\tns_per_lookup\ttexture_bytes\tfile\n";
    size_t n = dump.records.size();
    std::vector<float> pixels(n * 4, 0.0f);
    for (const Setting& s : settings) {
        TextureOpt opt;
        opt.mipmode = s.mip;
        opt.interpmode = s.interp;
        opt.anisotropic = s.aniso;
        opt.swrap = opt.twrap = TextureOpt::WrapDefault;  // from the .tx
        std::vector<double> times;
        size_t lookups = 0;
        // One warm-up pass fills the cache; then the timed passes.
        for (int pass = 0; pass <= passes; ++pass) {
            lookups = 0;
            auto start = std::chrono::steady_clock::now();
            for (size_t i = 0; i < n; ++i) {
                const Record& r = dump.records[i];
                if (r.texture == 0xFFFFFFFFu) continue;
                ts->texture(handles[r.texture], thread, opt, r.f[0], r.f[1], r.f[2], r.f[3],
                            r.f[4], r.f[5], 4, &pixels[4 * i]);
                ++lookups;
            }
            double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (pass > 0) times.push_back(dt);
        }
        std::sort(times.begin(), times.end());
        double median = times[times.size() / 2];
        std::string file;
        for (const char* c = s.name; *c; ++c) file += (*c == ' ') ? '-' : char(std::tolower(*c));
        file += ".exr";
        ImageBuf out(ImageSpec(dump.width, dump.height, 4, TypeDesc::FLOAT), pixels.data());
        if (!out.write(dir + "/" + file)) {
            std::cerr << "Error: writing " << file << ": " << out.geterror() << "\n";
            return 1;
        }
        std::printf("%s\t%.1f\t%llu\t%s\n", s.name, 1e9 * median / double(std::max<size_t>(lookups, 1)),
                    (unsigned long long)tx_bytes, file.c_str());
    }
    std::cerr << ts->getstats(1, true) << "\n";
    TextureSystem::destroy(ts);
    return 0;
}
