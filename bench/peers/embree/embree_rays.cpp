// Intel Embree 3 on quadtex's ray dump (`quadtex rays`, format documented
// in crates/quadtex-render/src/rays.rs): the same triangles in one Embree
// scene, the same primary rays cast closest-hit and the same sun shadow
// rays cast any-hit (occlusion), on one thread (device "threads=1"), timed
// as quadtex times its own: one untimed warm-up pass, then PASSES passes,
// median nanoseconds per ray. Rays are converted to Embree's f32 before the
// clock starts (quadtex's are f64, as the renderer makes them).
//
// Methods: single rays (rtcIntersect1 / rtcOccluded1, pixel order); packets
// of 4, 8 and 16 rays from 2x2, 4x2 and 4x4 tiles of neighbouring pixels
// (rtcIntersect4/8/16, rtcOccluded4/8/16; a shadow packet holds the shadow
// rays of its tile's pixels, the other lanes masked off); and streams
// (rtcIntersect1M / rtcOccluded1M) of the rays of 16x16 tiles. Packets and
// streams run with the context flag COHERENT. Denormals are flushed to
// zero (FTZ/DAZ), as Embree asks.
//
// Prints `method<TAB>ns_per_ray` lines and `build: WHAT<TAB>ms` (the
// scene's commit: Embree's BVH build, one thread) to stdout; to stderr, the
// device's properties and the check against quadtex's answers
// (quadtex-hits.bin): hit/miss, surface and triangle disagreements and the
// largest relative difference of t for primary rays, occlusion
// disagreements for shadow rays, for every method.
//
// Usage: embree_rays DIR [PASSES] [high|medium]
#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

struct Ray {
    double o[3], d[3], tmin, tmax;
};

struct Shadow {
    Ray ray;
    uint32_t pixel, surface, triangle;
};

struct Surface {
    uint32_t kind;  // 0 mesh, 1 quad
    std::vector<float> corners;  // 9 per triangle
};

struct Dump {
    uint32_t width = 0, height = 0;
    std::vector<Surface> surfaces;
    std::vector<Ray> primary;
    std::vector<Shadow> shadow;
};

struct Hit {
    uint32_t surface, triangle;
    double t;
};

struct Results {
    std::vector<Hit> primary;
    std::vector<uint8_t> shadow;  // bit 0: hierarchy, bit 1: renderer's path
};

template <class T>
static bool get(std::ifstream& in, T& v)
{
    return bool(in.read(reinterpret_cast<char*>(&v), sizeof v));
}

static bool get_ray(std::ifstream& in, Ray& r)
{
    double v[8];
    if (!in.read(reinterpret_cast<char*>(v), sizeof v)) return false;
    std::memcpy(r.o, v, 24);
    std::memcpy(r.d, v + 3, 24);
    r.tmin = v[6];
    r.tmax = v[7];
    return true;
}

static bool read_dump(const std::string& path, Dump& d)
{
    std::ifstream in(path, std::ios::binary);
    char magic[8];
    if (!in.read(magic, 8) || std::memcmp(magic, "QTXRAYS1", 8) != 0) return false;
    uint32_t n = 0;
    if (!get(in, d.width) || !get(in, d.height) || !get(in, n)) return false;
    for (uint32_t s = 0; s < n; ++s) {
        Surface surface;
        uint32_t count = 0;
        if (!get(in, surface.kind) || !get(in, count)) return false;
        surface.corners.resize(size_t(count) * 9);
        if (!in.read(reinterpret_cast<char*>(surface.corners.data()), surface.corners.size() * 4))
            return false;
        d.surfaces.push_back(std::move(surface));
    }
    if (!get(in, n)) return false;
    d.primary.resize(n);
    for (auto& r : d.primary)
        if (!get_ray(in, r)) return false;
    if (!get(in, n)) return false;
    d.shadow.resize(n);
    for (auto& s : d.shadow)
        if (!get_ray(in, s.ray) || !get(in, s.pixel) || !get(in, s.surface) || !get(in, s.triangle))
            return false;
    return true;
}

static bool read_results(const std::string& path, Results& r)
{
    std::ifstream in(path, std::ios::binary);
    char magic[8];
    if (!in.read(magic, 8) || std::memcmp(magic, "QTXHITS1", 8) != 0) return false;
    uint32_t n = 0;
    if (!get(in, n)) return false;
    r.primary.resize(n);
    for (auto& h : r.primary)
        if (!get(in, h.surface) || !get(in, h.triangle) || !get(in, h.t)) return false;
    if (!get(in, n)) return false;
    r.shadow.resize(n);
    return bool(in.read(reinterpret_cast<char*>(r.shadow.data()), n));
}

// A ray in Embree's precision.
struct RayF {
    float o[3], d[3], tnear, tfar;
};

static RayF to_f32(const Ray& r)
{
    RayF f;
    for (int k = 0; k < 3; ++k) {
        f.o[k] = float(r.o[k]);
        f.d[k] = float(r.d[k]);
    }
    f.tnear = float(r.tmin);
    f.tfar = std::isinf(r.tmax) ? INFINITY : float(r.tmax);
    return f;
}

static void set_ray1(RTCRay& ray, const RayF& r)
{
    ray.org_x = r.o[0];
    ray.org_y = r.o[1];
    ray.org_z = r.o[2];
    ray.dir_x = r.d[0];
    ray.dir_y = r.d[1];
    ray.dir_z = r.d[2];
    ray.tnear = r.tnear;
    ray.tfar = r.tfar;
    ray.time = 0.0f;
    ray.mask = 0xFFFFFFFFu;
    ray.id = 0;
    ray.flags = 0;
}

template <class RayN>
static void set_lane(RayN& ray, int i, const RayF& r)
{
    ray.org_x[i] = r.o[0];
    ray.org_y[i] = r.o[1];
    ray.org_z[i] = r.o[2];
    ray.dir_x[i] = r.d[0];
    ray.dir_y[i] = r.d[1];
    ray.dir_z[i] = r.d[2];
    ray.tnear[i] = r.tnear;
    ray.tfar[i] = r.tfar;
    ray.time[i] = 0.0f;
    ray.mask[i] = 0xFFFFFFFFu;
    ray.id[i] = 0;
    ray.flags[i] = 0;
}

// Per ray, what Embree answered: primary (geomID, primID, tfar), shadow
// (occluded).
struct Answers {
    std::vector<uint32_t> geom, prim;
    std::vector<float> t;
    std::vector<uint8_t> occluded;
};

// Groups ray indices by screen tiles of tw x th pixels (tile order, then
// row order inside a tile): `pixel_of[i]` is ray i's pixel; a tile's list
// holds at most one ray per pixel, -1 where its pixel has none.
static std::vector<std::vector<int64_t>> tiles(const std::vector<uint32_t>& pixel_of, uint32_t w,
                                               uint32_t h, uint32_t tw, uint32_t th)
{
    std::vector<int64_t> at(size_t(w) * h, -1);
    for (size_t i = 0; i < pixel_of.size(); ++i) at[pixel_of[i]] = int64_t(i);
    std::vector<std::vector<int64_t>> out;
    for (uint32_t ty = 0; ty < h; ty += th)
        for (uint32_t tx = 0; tx < w; tx += tw) {
            std::vector<int64_t> tile;
            for (uint32_t y = ty; y < std::min(h, ty + th); ++y)
                for (uint32_t x = tx; x < std::min(w, tx + tw); ++x) tile.push_back(at[size_t(y) * w + x]);
            out.push_back(std::move(tile));
        }
    return out;
}

// The ray and ray-hit types of a packet size.
template <class H, class R>
struct Packet {
    using RayHitN = H;
    using RayN = R;
};

static double median_ns(size_t count, int passes, const std::function<void()>& run)
{
    run();  // warm-up
    std::vector<double> times;
    for (int p = 0; p < passes; ++p) {
        auto start = std::chrono::steady_clock::now();
        run();
        times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    std::sort(times.begin(), times.end());
    return 1e9 * times[times.size() / 2] / double(std::max<size_t>(count, 1));
}

int main(int argc, char** argv)
{
    if (argc < 2) {
        std::cerr << "usage: embree_rays DIR [PASSES] [high|medium]\n";
        return 2;
    }
    // As Embree asks of every thread that casts rays (its start-up warns
    // otherwise): denormals flushed to zero.
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    std::string dir = argv[1];
    int passes = argc > 2 ? std::max(1, std::atoi(argv[2])) : 5;
    std::string quality_name = argc > 3 ? argv[3] : "high";
    RTCBuildQuality quality = quality_name == "medium" ? RTC_BUILD_QUALITY_MEDIUM : RTC_BUILD_QUALITY_HIGH;
    Dump dump;
    if (!read_dump(dir + "/rays.bin", dump)) {
        std::cerr << "Error: " << dir << "/rays.bin: not a readable ray dump\n";
        return 1;
    }
    Results quadtex;
    bool have_results = read_results(dir + "/quadtex-hits.bin", quadtex) &&
                        quadtex.primary.size() == dump.primary.size() &&
                        quadtex.shadow.size() == dump.shadow.size();
    if (!have_results) std::cerr << "warning: no matching quadtex-hits.bin: nothing checked\n";

    RTCDevice device = rtcNewDevice("threads=1");
    if (!device) {
        std::cerr << "Error: rtcNewDevice: " << rtcGetDeviceError(nullptr) << "\n";
        return 1;
    }
    std::cerr << "Embree " << RTC_VERSION_STRING << ", device threads=1; packets 4/8/16 natively supported: "
              << rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) << "/"
              << rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) << "/"
              << rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED)
              << ", streams: " << rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED)
              << "; build quality " << quality_name << "\n";
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, quality);
    size_t triangles = 0;
    for (size_t s = 0; s < dump.surfaces.size(); ++s) {
        const Surface& surface = dump.surfaces[s];
        size_t n = surface.corners.size() / 9;
        triangles += n;
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* v = static_cast<float*>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
        auto* idx = static_cast<unsigned*>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
        std::memcpy(v, surface.corners.data(), surface.corners.size() * sizeof(float));
        for (size_t i = 0; i < 3 * n; ++i) idx[i] = unsigned(i);
        rtcSetGeometryBuildQuality(g, quality);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(scene, g, unsigned(s));
        rtcReleaseGeometry(g);
    }
    auto build_start = std::chrono::steady_clock::now();
    rtcCommitScene(scene);
    double build_ms =
        1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - build_start).count();
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) {
        std::cerr << "Error: Embree scene build failed\n";
        return 1;
    }
    std::cerr << triangles << " triangles in " << dump.surfaces.size() << " geometries; "
              << dump.primary.size() << " primary rays, " << dump.shadow.size() << " shadow rays\n";

    const size_t np = dump.primary.size(), ns = dump.shadow.size();
    std::vector<RayF> primary(np), shadow(ns);
    for (size_t i = 0; i < np; ++i) primary[i] = to_f32(dump.primary[i]);
    for (size_t i = 0; i < ns; ++i) shadow[i] = to_f32(dump.shadow[i].ray);
    std::vector<uint32_t> primary_pixel(np), shadow_pixel(ns);
    for (size_t i = 0; i < np; ++i) primary_pixel[i] = uint32_t(i);
    for (size_t i = 0; i < ns; ++i) shadow_pixel[i] = dump.shadow[i].pixel;

    Answers answers;
    answers.geom.assign(np, RTC_INVALID_GEOMETRY_ID);
    answers.prim.assign(np, 0);
    answers.t.assign(np, INFINITY);
    answers.occluded.assign(ns, 0);

    RTCIntersectContext incoherent, coherent;
    rtcInitIntersectContext(&incoherent);
    rtcInitIntersectContext(&coherent);
    coherent.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;

    // The methods, each filling `answers`.
    struct Method {
        std::string name;
        bool is_primary;
        std::function<void()> run;
    };
    std::vector<Method> methods;
    methods.push_back({"Embree primary rtcIntersect1", true, [&] {
                           RTCRayHit rh;
                           for (size_t i = 0; i < np; ++i) {
                               set_ray1(rh.ray, primary[i]);
                               rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                               rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                               rtcIntersect1(scene, &incoherent, &rh);
                               answers.geom[i] = rh.hit.geomID;
                               answers.prim[i] = rh.hit.primID;
                               answers.t[i] = rh.ray.tfar;
                           }
                       }});
    methods.push_back({"Embree shadow rtcOccluded1", false, [&] {
                           RTCRay ray;
                           for (size_t i = 0; i < ns; ++i) {
                               set_ray1(ray, shadow[i]);
                               rtcOccluded1(scene, &incoherent, &ray);
                               answers.occluded[i] = ray.tfar < 0.0f;
                           }
                       }});
    // Packets of N rays from tiles tw x th.
    auto packets = [&](auto tag, uint32_t tw, uint32_t th, const char* size) {
        using RayHitN = typename decltype(tag)::RayHitN;
        using RayN = typename decltype(tag)::RayN;
        constexpr int N = sizeof(RayN::tnear) / sizeof(float);
        auto ptiles = std::make_shared<std::vector<std::vector<int64_t>>>(
            tiles(primary_pixel, dump.width, dump.height, tw, th));
        auto stiles = std::make_shared<std::vector<std::vector<int64_t>>>(
            tiles(shadow_pixel, dump.width, dump.height, tw, th));
        std::string n = std::to_string(N);
        methods.push_back({"Embree primary rtcIntersect" + n + " (" + size + " tiles)", true, [&, ptiles] {
                               alignas(64) RayHitN rh;
                               alignas(64) int valid[N];
                               for (const auto& tile : *ptiles) {
                                   for (int k = 0; k < N; ++k) {
                                       int64_t i = k < int(tile.size()) ? tile[k] : -1;
                                       valid[k] = i < 0 ? 0 : -1;
                                       set_lane(rh.ray, k, i < 0 ? primary[0] : primary[size_t(i)]);
                                       rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
                                       rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
                                   }
                                   if constexpr (N == 4) rtcIntersect4(valid, scene, &coherent, &rh);
                                   if constexpr (N == 8) rtcIntersect8(valid, scene, &coherent, &rh);
                                   if constexpr (N == 16) rtcIntersect16(valid, scene, &coherent, &rh);
                                   for (int k = 0; k < N && k < int(tile.size()); ++k) {
                                       if (tile[k] < 0) continue;
                                       size_t i = size_t(tile[k]);
                                       answers.geom[i] = rh.hit.geomID[k];
                                       answers.prim[i] = rh.hit.primID[k];
                                       answers.t[i] = rh.ray.tfar[k];
                                   }
                               }
                           }});
        methods.push_back({"Embree shadow rtcOccluded" + n + " (" + size + " tiles)", false, [&, stiles] {
                               alignas(64) RayN ray;
                               alignas(64) int valid[N];
                               for (const auto& tile : *stiles) {
                                   bool any = false;
                                   for (int k = 0; k < N; ++k) {
                                       int64_t i = k < int(tile.size()) ? tile[k] : -1;
                                       valid[k] = i < 0 ? 0 : -1;
                                       any |= i >= 0;
                                       set_lane(ray, k, i < 0 ? shadow.empty() ? RayF{} : shadow[0] : shadow[size_t(i)]);
                                   }
                                   if (!any) continue;
                                   if constexpr (N == 4) rtcOccluded4(valid, scene, &coherent, &ray);
                                   if constexpr (N == 8) rtcOccluded8(valid, scene, &coherent, &ray);
                                   if constexpr (N == 16) rtcOccluded16(valid, scene, &coherent, &ray);
                                   for (int k = 0; k < N && k < int(tile.size()); ++k)
                                       if (tile[k] >= 0) answers.occluded[size_t(tile[k])] = ray.tfar[k] < 0.0f;
                               }
                           }});
    };
    packets(Packet<RTCRayHit4, RTCRay4>{}, 2, 2, "2x2");
    packets(Packet<RTCRayHit8, RTCRay8>{}, 4, 2, "4x2");
    packets(Packet<RTCRayHit16, RTCRay16>{}, 4, 4, "4x4");
    // Streams: the rays of 16x16 tiles, one call per tile.
    auto pstream = tiles(primary_pixel, dump.width, dump.height, 16, 16);
    auto sstream = tiles(shadow_pixel, dump.width, dump.height, 16, 16);
    std::vector<RTCRayHit> stream_hits(256);
    std::vector<RTCRay> stream_rays(256);
    methods.push_back({"Embree primary rtcIntersect1M (16x16 tiles)", true, [&] {
                           for (const auto& tile : pstream) {
                               unsigned m = 0;
                               for (int64_t i : tile) {
                                   if (i < 0) continue;
                                   RTCRayHit& rh = stream_hits[m++];
                                   set_ray1(rh.ray, primary[size_t(i)]);
                                   rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                                   rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                               }
                               rtcIntersect1M(scene, &coherent, stream_hits.data(), m, sizeof(RTCRayHit));
                               m = 0;
                               for (int64_t i : tile) {
                                   if (i < 0) continue;
                                   const RTCRayHit& rh = stream_hits[m++];
                                   answers.geom[size_t(i)] = rh.hit.geomID;
                                   answers.prim[size_t(i)] = rh.hit.primID;
                                   answers.t[size_t(i)] = rh.ray.tfar;
                               }
                           }
                       }});
    methods.push_back({"Embree shadow rtcOccluded1M (16x16 tiles)", false, [&] {
                           for (const auto& tile : sstream) {
                               unsigned m = 0;
                               for (int64_t i : tile)
                                   if (i >= 0) set_ray1(stream_rays[m++], shadow[size_t(i)]);
                               if (m == 0) continue;
                               rtcOccluded1M(scene, &coherent, stream_rays.data(), m, sizeof(RTCRay));
                               m = 0;
                               for (int64_t i : tile)
                                   if (i >= 0) answers.occluded[size_t(i)] = stream_rays[m++].tfar < 0.0f;
                           }
                       }});

    // Primary methods first, then shadow ones (the table's order).
    std::stable_partition(methods.begin(), methods.end(), [](const Method& m) { return m.is_primary; });
    for (const Method& m : methods) {
        double ns_per_ray = median_ns(m.is_primary ? np : ns, passes, m.run);
        std::cout << m.name << "\t" << ns_per_ray << "\n" << std::flush;
        if (!have_results) continue;
        // The check against quadtex's answers (the last pass's).
        if (m.is_primary) {
            size_t hit_miss = 0, surface = 0, triangle = 0, triangle_same_t = 0, hits = 0;
            double max_rel = 0.0;
            for (size_t i = 0; i < np; ++i) {
                const Hit& q = quadtex.primary[i];
                bool qh = q.surface != 0xFFFFFFFFu, eh = answers.geom[i] != RTC_INVALID_GEOMETRY_ID;
                if (qh != eh) {
                    ++hit_miss;
                    continue;
                }
                if (!qh) continue;
                ++hits;
                double rel = std::fabs(double(answers.t[i]) - q.t) / q.t;
                if (answers.geom[i] != q.surface) {
                    ++surface;
                    continue;
                }
                if (dump.surfaces[q.surface].kind == 0 && answers.prim[i] != q.triangle) {
                    ++triangle;
                    if (rel < 1e-5) ++triangle_same_t;
                    continue;
                }
                max_rel = std::max(max_rel, rel);
            }
            std::cerr << m.name << ": " << hits << " hits both; hit/miss disagreements " << hit_miss
                      << ", other surface " << surface << ", other triangle of the mesh " << triangle
                      << " (" << triangle_same_t << " of them at the same t within 1e-5)"
                      << "; max relative t difference where both agree " << max_rel << "\n";
        } else {
            size_t bvh = 0, renderer = 0, occluded = 0;
            for (size_t i = 0; i < ns; ++i) {
                bool e = answers.occluded[i] != 0;
                occluded += e;
                bvh += e != bool(quadtex.shadow[i] & 1);
                renderer += e != bool(quadtex.shadow[i] & 2);
            }
            std::cerr << m.name << ": " << occluded << " of " << ns
                      << " occluded; disagreements with quadtex's hierarchy any-hit " << bvh
                      << ", with the renderer's path " << renderer << "\n";
        }
    }
    std::cout << "build: Embree BVH (quality " << quality_name << ")\t" << build_ms << "\n";
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    return 0;
}
