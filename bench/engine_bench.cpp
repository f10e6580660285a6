// What an engine pays per codec, mocodec beside ACL 2.1 in one process (bench/engine_bench.py runs it).
//
//   engine_bench tune DUMP --target-cm E [--shell S] --out PRECISIONS.csv
//       ACL: per clip, the precision with the fewest bytes whose max world error is <= E cm
//   engine_bench run DUMP [--acl E=PRECISIONS.csv]... [--mcd CODEC:E=ASSET.mcd]... [--no-acl WHY]
//                    [--shell S] [--rounds N] [--compress-reps N] [--open-reps N] --json OUT.json
//       sizes, engine bytes, open time, ACL compression time, and decode µs per pose, ACL and
//       mocodec passes interleaved in rounds
//   engine_bench speed ASSET.mcd [runs] [local-seq|local-rand|world-seq|world-rand]
//       mocodec alone, one JSON line (what bench/run_bench.py and friends read)
//
// DUMP is written by engine_bench.py from the project's BVH reader: per clip the parents, the
// frame rate, float32 local rotation + translation per frame and node (ACL's input) and the
// float64 world position of every node (the error reference), so no BVH parsing happens here.
//
// Compiled with -DMCD_BENCH_ACL=1 and ACL 2.1 / rtm 2.2 on the include path for the ACL part;
// without it, `run` measures mocodec alone and says so.
#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#if MCD_BENCH_ACL
#include <acl/compression/compress.h>
#include <acl/compression/track_array.h>
#include <acl/compression/transform_error_metrics.h>
#include <acl/core/ansi_allocator.h>
#include <acl/decompression/decompress.h>
#endif

#include "mocodec.h"

#ifndef MCD_BENCH_RUNTIME_FLAGS
#define MCD_BENCH_RUNTIME_FLAGS "unknown"
#endif

namespace {

constexpr uint32_t kMaxNodes = 256;
constexpr int kTickInstances = 8;
constexpr double kTickHz = 60.0;
constexpr uint64_t kSeed = 0x9E3779B97F4A7C15ull;

[[noreturn]] void fail(const char* fmt, ...) {
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    throw std::runtime_error(msg);
}

double cpu_s() {  // this thread's CPU time: a shared machine's descheduled time is not work
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

double wall_s() {
    timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

// Keeps the compiler from dropping stores to a pose nobody reads.
inline void consume(const void* p) { asm volatile("" : : "r"(p) : "memory"); }

struct Summary {
    double median = NAN, p25 = NAN, p75 = NAN, min = NAN, max = NAN;
};

double quantile(std::vector<double> v, double q) {
    if (v.empty()) return NAN;
    std::sort(v.begin(), v.end());
    const double x = q * double(v.size() - 1);
    const size_t i = size_t(x);
    return i + 1 < v.size() ? v[i] + (x - double(i)) * (v[i + 1] - v[i]) : v[i];
}

Summary summarize(const std::vector<double>& v) {
    return {quantile(v, 0.5), quantile(v, 0.25), quantile(v, 0.75), quantile(v, 0.0), quantile(v, 1.0)};
}

struct Rng {  // xorshift64*: the same times for every subject and every run
    uint64_t s = kSeed;
    double uniform01() {
        s ^= s >> 12; s ^= s << 25; s ^= s >> 27;
        return double((s * 2685821657736338717ull) >> 11) / 9007199254740992.0;
    }
};

struct Buffer {  // 64-byte aligned bytes
    void* p = nullptr;
    size_t n = 0;
    Buffer() = default;
    explicit Buffer(size_t size) : n(size) {
        if (posix_memalign(&p, 64, size ? size : 64) != 0) throw std::bad_alloc();
        std::memset(p, 0, size ? size : 64);
    }
    Buffer(const Buffer&) = delete;
    Buffer& operator=(const Buffer&) = delete;
    Buffer(Buffer&& o) noexcept : p(o.p), n(o.n) { o.p = nullptr; o.n = 0; }
    Buffer& operator=(Buffer&& o) noexcept { std::swap(p, o.p); std::swap(n, o.n); return *this; }
    ~Buffer() { std::free(p); }
    uint8_t* bytes() const { return static_cast<uint8_t*>(p); }
};

Buffer read_file(const std::string& path) {
    FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) fail("%s: cannot open (%s)", path.c_str(), std::strerror(errno));
    std::fseek(f, 0, SEEK_END);
    const long size = std::ftell(f);
    std::fseek(f, 0, SEEK_SET);
    Buffer b(size_t(size < 0 ? 0 : size));
    const bool ok = size >= 0 && std::fread(b.p, 1, b.n, f) == b.n;
    std::fclose(f);
    if (!ok) fail("%s: read failed", path.c_str());
    return b;
}

// ------------------------------------------------------------------------------- the clips
struct Clip {
    std::string name;
    uint32_t nodes = 0, frames = 0, channels = 0;
    double rate = 0;            // frames per second
    float rate_f = 0;           // what both libraries are given
    std::vector<int32_t> parents;
    std::vector<float> local;   // frames * nodes * 7: qx qy qz qw tx ty tz
    std::vector<double> world;  // frames * nodes * 3, file units
    float duration() const { return frames > 1 ? float(frames - 1) / rate_f : 0.0f; }
};

struct Clips {
    std::vector<Clip> clips;
    double cm_per_unit = 0;
    size_t frames = 0, node_frames = 0, raw_acl_bytes = 0, raw_bvh_bytes = 0;
};

struct Reader {  // bounds-checked little-endian reads from the dump
    const uint8_t* p;
    size_t n, at = 0;
    const std::string& path;
    void take(void* out, size_t k) {
        if (k > n - at) fail("%s: truncated at byte %zu", path.c_str(), at);
        std::memcpy(out, p + at, k);
        at += k;
    }
    template <class T> T get() { T v; take(&v, sizeof v); return v; }
};

Clips read_dump(const std::string& path) {
    Buffer file = read_file(path);
    Reader r{file.bytes(), file.n, 0, path};
    char magic[8];
    r.take(magic, 8);
    if (std::memcmp(magic, "MCDBDUMP", 8) != 0) fail("%s: not a clip dump of engine_bench.py", path.c_str());
    if (r.get<uint32_t>() != 1) fail("%s: dump version is not 1 (rewrite it with engine_bench.py)", path.c_str());
    const uint32_t count = r.get<uint32_t>();
    Clips out;
    out.cm_per_unit = r.get<double>();
    for (uint32_t c = 0; c < count; ++c) {
        Clip k;
        const uint32_t len = r.get<uint32_t>();
        if (len > 4096) fail("%s: clip %u: name length %u", path.c_str(), c, len);
        k.name.resize(len);
        r.take(&k.name[0], len);
        k.nodes = r.get<uint32_t>();
        k.frames = r.get<uint32_t>();
        k.channels = r.get<uint32_t>();
        k.rate = r.get<double>();
        k.rate_f = float(k.rate);
        if (k.nodes == 0 || k.nodes > kMaxNodes || k.frames == 0 || !(k.rate > 0))
            fail("%s: clip %s: %u nodes, %u frames, rate %g", path.c_str(), k.name.c_str(), k.nodes, k.frames, k.rate);
        k.parents.resize(k.nodes);
        r.take(k.parents.data(), k.nodes * sizeof(int32_t));
        for (uint32_t i = 0; i < k.nodes; ++i)
            if (k.parents[i] < -1 || k.parents[i] >= int32_t(i))
                fail("%s: clip %s: node %u has parent %d", path.c_str(), k.name.c_str(), i, k.parents[i]);
        const size_t nf = size_t(k.frames) * k.nodes;
        k.local.resize(nf * 7);
        r.take(k.local.data(), k.local.size() * sizeof(float));
        k.world.resize(nf * 3);
        r.take(k.world.data(), k.world.size() * sizeof(double));
        out.frames += k.frames;
        out.node_frames += nf;
        out.raw_acl_bytes += nf * 40;  // ACL's convention: 40 B per bone-sample
        out.raw_bvh_bytes += size_t(k.frames) * k.channels * 4;
        out.clips.push_back(std::move(k));
    }
    if (r.at != r.n) fail("%s: %zu trailing bytes", path.c_str(), r.n - r.at);
    if (out.clips.empty()) fail("%s: no clips", path.c_str());
    return out;
}

// Max world-position error (cm) of a pose given as double local rotations (x y z w) and
// translations, against the reference of one frame: double FK, parents first.
double pose_error_cm(const Clip& c, uint32_t frame, const double* rot, const double* trans, double cm_per_unit) {
    double wr[kMaxNodes][4], wp[kMaxNodes][3], worst = 0;
    const double* ref = &c.world[size_t(frame) * c.nodes * 3];
    for (uint32_t i = 0; i < c.nodes; ++i) {
        const double* q = rot + 4 * i;
        const double* t = trans + 3 * i;
        const int p = c.parents[i];
        if (p < 0) {
            std::memcpy(wr[i], q, sizeof wr[i]);
            std::memcpy(wp[i], t, sizeof wp[i]);
        } else {
            const double* a = wr[p];
            // world rotation = parent * local (Hamilton, x y z w)
            wr[i][0] = a[3] * q[0] + a[0] * q[3] + a[1] * q[2] - a[2] * q[1];
            wr[i][1] = a[3] * q[1] - a[0] * q[2] + a[1] * q[3] + a[2] * q[0];
            wr[i][2] = a[3] * q[2] + a[0] * q[1] - a[1] * q[0] + a[2] * q[3];
            wr[i][3] = a[3] * q[3] - a[0] * q[0] - a[1] * q[1] - a[2] * q[2];
            // position = parent position + parent rotation applied to the local translation
            const double ux = 2 * (a[1] * t[2] - a[2] * t[1]);
            const double uy = 2 * (a[2] * t[0] - a[0] * t[2]);
            const double uz = 2 * (a[0] * t[1] - a[1] * t[0]);
            wp[i][0] = wp[p][0] + t[0] + a[3] * ux + (a[1] * uz - a[2] * uy);
            wp[i][1] = wp[p][1] + t[1] + a[3] * uy + (a[2] * ux - a[0] * uz);
            wp[i][2] = wp[p][2] + t[2] + a[3] * uz + (a[0] * uy - a[1] * ux);
        }
        const double dx = wp[i][0] - ref[3 * i], dy = wp[i][1] - ref[3 * i + 1], dz = wp[i][2] - ref[3 * i + 2];
        worst = std::max(worst, std::sqrt(dx * dx + dy * dy + dz * dz) * cm_per_unit);
    }
    return worst;
}

// Max distance (cm) between float world positions and the reference, one frame.
double world_error_cm(const Clip& c, uint32_t frame, const float* xyz, size_t stride, double cm_per_unit) {
    const double* ref = &c.world[size_t(frame) * c.nodes * 3];
    double worst = 0;
    for (uint32_t i = 0; i < c.nodes; ++i) {
        const float* p = xyz + i * stride;
        const double dx = p[0] - ref[3 * i], dy = p[1] - ref[3 * i + 1], dz = p[2] - ref[3 * i + 2];
        worst = std::max(worst, std::sqrt(dx * dx + dy * dy + dz * dz) * cm_per_unit);
    }
    return worst;
}

// ------------------------------------------------------------------------------ workloads
// A pass is a list of steps: sample clip `clip` at `time` with instance `instance`'s scratch
// or ACL context. Instance 0 serves sequential and random access; 1..8 the game tick.
struct Step {
    uint32_t clip;
    float time;
    uint32_t instance;
};

struct Workloads {
    std::vector<Step> sequential, tick, random;
    std::vector<uint32_t> tick_clips;
    uint32_t ticks = 0;
};

struct Mode {
    const char* key;
    const char* label;
    std::vector<Step> Workloads::*steps;  // a member pointer: stays right when Workloads moves
    bool world;
};

const Mode kModes[] = {{"seq_local", "sequential, local", &Workloads::sequential, false},
                       {"tick_local", "game tick, local", &Workloads::tick, false},
                       {"random_local", "random, local", &Workloads::random, false},
                       {"seq_world", "sequential, world", &Workloads::sequential, true},
                       {"tick_world", "game tick, world", &Workloads::tick, true},
                       {"random_world", "random, world", &Workloads::random, true}};

// Clip lengths as (frames, rate) per clip index.
Workloads make_workloads(const std::vector<std::pair<uint32_t, float>>& clips) {
    Workloads w;
    Rng rng;
    size_t total = 0;
    for (uint32_t c = 0; c < clips.size(); ++c) {
        const uint32_t frames = clips[c].first;
        const float rate = clips[c].second, duration = frames > 1 ? float(frames - 1) / rate : 0.0f;
        for (uint32_t i = 0; i < frames; ++i) w.sequential.push_back({c, float(i) / rate, 0});
        for (uint32_t i = 0; i < frames; ++i) w.random.push_back({c, float(rng.uniform01() * duration), 0});
        total += frames;
    }
    // Game tick: 8 instances of different clips (spread over the set), each advancing by
    // 1/60 s per tick in turn and looping; as many poses as the sequential pass.
    const uint32_t n = uint32_t(clips.size());
    for (int k = 0; k < kTickInstances; ++k) w.tick_clips.push_back(uint32_t((uint64_t(k) * n) / kTickInstances));
    w.ticks = uint32_t(std::max<size_t>(1, total / kTickInstances));
    for (uint32_t j = 0; j < w.ticks; ++j)
        for (int k = 0; k < kTickInstances; ++k) {
            const uint32_t c = w.tick_clips[k];
            const double duration = clips[c].first > 1 ? double(clips[c].first - 1) / clips[c].second : 0.0;
            const double t = duration > 0 ? std::fmod(j / kTickHz, duration) : 0.0;
            w.tick.push_back({c, float(t), uint32_t(1 + k)});
        }
    return w;
}

struct PassTime {
    double cpu_us, wall_us;  // per pose
};

// ------------------------------------------------------------------------------- mocodec
struct McdSubject {
    std::string label, codec;
    double tolerance_cm = 0;
    Buffer bytes, resident;
    mcd_asset asset{};
    size_t scratch_bytes = 0;
    std::vector<Buffer> scratch;     // 1 + kTickInstances
    std::vector<uint32_t> clip_map;  // dump clip -> asset clip
    double max_cm = NAN, world_max_cm = NAN;
};

void open_mcd(McdSubject& m, const std::string& path) {
    m.bytes = read_file(path);
    mcd_result r;
#if MCD_FORMAT_MAJOR >= 2
    r = mcd_open(m.bytes.p, m.bytes.n, 0, &m.asset);
#else
    size_t rs = 0;
    r = mcd_resident_size(m.bytes.p, m.bytes.n, 0, &rs);
    if (r == MCD_OK) {
        m.resident = Buffer(rs);
        r = mcd_open(m.bytes.p, m.bytes.n, 0, m.resident.p, rs, &m.asset);
    }
#endif
    if (r != MCD_OK) fail("%s: cannot open: %s", path.c_str(), mcd_result_string(r));
    m.scratch_bytes = mcd_scratch_size(&m.asset);
    for (int k = 0; k <= kTickInstances; ++k) {
        m.scratch.emplace_back(m.scratch_bytes);
        r = mcd_scratch_init(&m.asset, m.scratch.back().p, m.scratch_bytes);
        if (r != MCD_OK) fail("%s: scratch: %s", path.c_str(), mcd_result_string(r));
    }
}

void map_clips(McdSubject& m, const Clips& set) {
    for (const Clip& c : set.clips) {
        uint32_t idx;
        mcd_clip_info info;
        if (mcd_find_clip(&m.asset, c.name.c_str(), &idx) != MCD_OK) fail("%s: no clip %s", m.label.c_str(), c.name.c_str());
        mcd_get_clip_info(&m.asset, idx, &info);
        if (info.node_count != c.nodes || info.frame_count != c.frames)
            fail("%s: clip %s has %u nodes, %u frames; the clips have %u, %u", m.label.c_str(), c.name.c_str(),
                 info.node_count, info.frame_count, c.nodes, c.frames);
        m.clip_map.push_back(idx);
    }
}

alignas(64) mcd_transform g_mcd_pose[kMaxNodes];

PassTime pass_mcd(McdSubject& m, const std::vector<Step>& steps, bool world) {
    const uint32_t flags = world ? MCD_SAMPLE_WORLD : 0u;
    const uint32_t* map = m.clip_map.data();
    void* scratch[1 + kTickInstances];
    for (int k = 0; k <= kTickInstances; ++k) scratch[k] = m.scratch[k].p;
    const double c0 = cpu_s(), w0 = wall_s();
    for (const Step& s : steps) {
        if (mcd_sample(&m.asset, map[s.clip], s.time, flags, g_mcd_pose, kMaxNodes, scratch[s.instance]) != MCD_OK)
            std::abort();
        consume(g_mcd_pose);
    }
    const double dc = cpu_s() - c0, dw = wall_s() - w0;
    return {dc * 1e6 / double(steps.size()), dw * 1e6 / double(steps.size())};
}

// World error at every frame (nearest frame), as the encoder measures it, from this process.
double mcd_max_error(McdSubject& m, const Clips& set) {
    double lr[kMaxNodes * 4], lt[kMaxNodes * 3], worst = 0;
    for (size_t c = 0; c < set.clips.size(); ++c) {
        const Clip& k = set.clips[c];
        for (uint32_t f = 0; f < k.frames; ++f) {
            mcd_result r = mcd_sample(&m.asset, m.clip_map[c], float(f) / k.rate_f, MCD_SAMPLE_NEAREST, g_mcd_pose,
                                      kMaxNodes, m.scratch[0].p);
            if (r != MCD_OK) fail("%s: sample %s frame %u: %s", m.label.c_str(), k.name.c_str(), f, mcd_result_string(r));
            for (uint32_t i = 0; i < k.nodes; ++i) {
                for (int a = 0; a < 4; ++a) lr[4 * i + a] = g_mcd_pose[i].rotation[a];
                for (int a = 0; a < 3; ++a) lt[3 * i + a] = g_mcd_pose[i].translation[a];
            }
            worst = std::max(worst, pose_error_cm(k, f, lr, lt, set.cm_per_unit));
        }
    }
    return worst;
}

// The world path that is timed, checked once: every frame through MCD_SAMPLE_WORLD.
double mcd_world_error(McdSubject& m, const Clips& set) {
    double worst = 0;
    for (size_t c = 0; c < set.clips.size(); ++c) {
        const Clip& k = set.clips[c];
        for (uint32_t f = 0; f < k.frames; ++f) {
            if (mcd_sample(&m.asset, m.clip_map[c], float(f) / k.rate_f, MCD_SAMPLE_WORLD, g_mcd_pose, kMaxNodes,
                           m.scratch[0].p) != MCD_OK)
                fail("%s: world sample failed", m.label.c_str());
            worst = std::max(worst, world_error_cm(k, f, g_mcd_pose[0].translation, sizeof(mcd_transform) / sizeof(float),
                                                   set.cm_per_unit));
        }
    }
    return worst;
}

// Times the ways of opening an asset (µs, thread CPU), each repeated enough to be measurable.
struct Timer {
    std::string name;
    std::function<void()> op;
    int repeat = 1;
    std::vector<double> us;
    Timer(std::string n, std::function<void()> f) : name(std::move(n)), op(std::move(f)) {}
};

void calibrate(Timer& t, double min_us) {
    t.op();  // warm
    const double c0 = cpu_s();
    t.op();
    const double one = (cpu_s() - c0) * 1e6;
    t.repeat = one >= min_us ? 1 : int(std::min(100000.0, std::ceil(min_us / std::max(one, 0.01))));
}

void time_once(Timer& t) {
    const double c0 = cpu_s();
    for (int i = 0; i < t.repeat; ++i) t.op();
    t.us.push_back((cpu_s() - c0) * 1e6 / t.repeat);
}

std::vector<Timer> mcd_open_timers(McdSubject& m) {
    std::vector<Timer> ts;
    auto open_with = [&m](uint32_t flags) {
        return [&m, flags] {
            mcd_asset a;
            mcd_result r;
#if MCD_FORMAT_MAJOR >= 2
            r = mcd_open(m.bytes.p, m.bytes.n, flags, &a);
#else
            r = mcd_open(m.bytes.p, m.bytes.n, flags, m.resident.p, m.resident.n, &a);
#endif
            if (r != MCD_OK) std::abort();
            consume(&a);
        };
    };
    ts.emplace_back("open", open_with(0));
    ts.emplace_back("open_no_crc", open_with(MCD_VALIDATE_SKIP_CHECKSUM));
#if MCD_FORMAT_MAJOR >= 2
    ts.emplace_back("open_prevalidated", open_with(MCD_OPEN_PREVALIDATED));
#else
    ts.emplace_back("resident_size", [&m] {
                      size_t rs;
                      if (mcd_resident_size(m.bytes.p, m.bytes.n, 0, &rs) != MCD_OK) std::abort();
                      consume(&rs);
                  });
#endif
    ts.emplace_back("scratch_init", [&m] {
                      if (mcd_scratch_init(&m.asset, m.scratch[0].p, m.scratch_bytes) != MCD_OK) std::abort();
                  });
    return ts;
}

// ------------------------------------------------------------------------------------ ACL
#if MCD_BENCH_ACL
acl::ansi_allocator g_alloc;
using Context = acl::decompression_context<acl::default_transform_decompression_settings>;

struct PoseWriter final : acl::track_writer {
    rtm::qvvf* pose;
    explicit PoseWriter(rtm::qvvf* p) : pose(p) {}
    void RTM_SIMD_CALL write_rotation(uint32_t i, rtm::quatf_arg0 r) { pose[i].rotation = r; }
    void RTM_SIMD_CALL write_translation(uint32_t i, rtm::vector4f_arg0 t) { pose[i].translation = t; }
    void RTM_SIMD_CALL write_scale(uint32_t i, rtm::vector4f_arg0 s) { pose[i].scale = s; }
};

alignas(64) rtm::qvvf g_acl_pose[kMaxNodes];

struct AclClip {  // one compressed clip, owned
    acl::compressed_tracks* tracks = nullptr;
    AclClip() = default;
    AclClip(const AclClip&) = delete;
    AclClip& operator=(const AclClip&) = delete;
    AclClip(AclClip&& o) noexcept : tracks(o.tracks) { o.tracks = nullptr; }
    AclClip& operator=(AclClip&& o) noexcept { std::swap(tracks, o.tracks); return *this; }
    ~AclClip() { if (tracks) g_alloc.deallocate(tracks, tracks->get_size()); }
};

// One track_qvvf per node, every track at the same precision and shell distance.
acl::track_array_qvvf make_tracks(const Clip& c, float precision, float shell) {
    acl::track_array_qvvf tracks(g_alloc, c.nodes);
    for (uint32_t i = 0; i < c.nodes; ++i) {
        acl::track_desc_transformf d;
        d.output_index = i;
        d.parent_index = c.parents[i] < 0 ? acl::k_invalid_track_index : uint32_t(c.parents[i]);
        d.precision = precision;
        d.shell_distance = shell;
        acl::track_qvvf t = acl::track_qvvf::make_reserve(d, g_alloc, c.frames, c.rate_f);
        for (uint32_t f = 0; f < c.frames; ++f) {
            const float* v = &c.local[(size_t(f) * c.nodes + i) * 7];
            t[f] = rtm::qvv_set(rtm::quat_set(v[0], v[1], v[2], v[3]), rtm::vector_set(v[4], v[5], v[6]),
                                rtm::vector_set(1.0F));
        }
        tracks[i] = std::move(t);
    }
    return tracks;
}

// Compresses with the default settings and the qvvf metric; returns the thread-CPU seconds of
// compress_track_list alone.
double compress(const Clip& c, float precision, float shell, AclClip& out) {
    acl::track_array_qvvf tracks = make_tracks(c, precision, shell);
    acl::compression_settings settings = acl::get_default_compression_settings();
    acl::qvvf_transform_error_metric metric;
    settings.error_metric = &metric;
    acl::output_stats stats;
    acl::compressed_tracks* result = nullptr;
    const double c0 = cpu_s();
    const acl::error_result err = acl::compress_track_list(g_alloc, tracks, settings, result, stats);
    const double seconds = cpu_s() - c0;
    if (err.any()) fail("ACL: clip %s at precision %g: %s", c.name.c_str(), precision, err.c_str());
    out = AclClip();
    out.tracks = result;
    return seconds;
}

// Max world error (cm) over every frame: decoded at the frame (nearest sample, or
// interpolated when keyframes were stripped), double FK against the reference.
double acl_max_error(const Clip& c, const acl::compressed_tracks& tracks, double cm_per_unit) {
    Context ctx;
    if (!ctx.initialize(tracks)) fail("ACL: clip %s: context initialisation failed", c.name.c_str());
    const acl::sample_rounding_policy policy =
        tracks.has_stripped_keyframes() ? acl::sample_rounding_policy::none : acl::sample_rounding_policy::nearest;
    PoseWriter writer(g_acl_pose);
    double lr[kMaxNodes * 4], lt[kMaxNodes * 3], worst = 0;
    const float duration = tracks.get_finite_duration();
    for (uint32_t f = 0; f < c.frames; ++f) {
        ctx.seek(std::min(float(f) / tracks.get_sample_rate(), duration), policy);
        ctx.decompress_tracks(writer);
        for (uint32_t i = 0; i < c.nodes; ++i) {
            lr[4 * i + 0] = rtm::quat_get_x(g_acl_pose[i].rotation);
            lr[4 * i + 1] = rtm::quat_get_y(g_acl_pose[i].rotation);
            lr[4 * i + 2] = rtm::quat_get_z(g_acl_pose[i].rotation);
            lr[4 * i + 3] = rtm::quat_get_w(g_acl_pose[i].rotation);
            lt[3 * i + 0] = rtm::vector_get_x(g_acl_pose[i].translation);
            lt[3 * i + 1] = rtm::vector_get_y(g_acl_pose[i].translation);
            lt[3 * i + 2] = rtm::vector_get_z(g_acl_pose[i].translation);
        }
        worst = std::max(worst, pose_error_cm(c, f, lr, lt, cm_per_unit));
    }
    return worst;
}

struct Trial {
    float precision;
    uint32_t bytes;
    double max_cm;
};

// Per clip: bracket the precision by factors of 1.5 around target / 1.5 (in file units), then 7
// steps of bisection in log precision; keep the trial with the fewest bytes at max <= target,
// or, when none meets it (ACL's error has a floor on some clips), the lowest error.
struct Tuned {
    Trial best;
    bool met;
    int trials;
};

Tuned tune_clip(const Clip& c, double target_cm, double cm_per_unit, float shell) {
    std::vector<Trial> trials;
    auto trial = [&](double p) {
        AclClip a;
        compress(c, float(p), shell, a);
        trials.push_back({float(p), a.tracks->get_size(), acl_max_error(c, *a.tracks, cm_per_unit)});
        return trials.back().max_cm <= target_cm;
    };
    const double start = target_cm / cm_per_unit / 1.5;
    double ok = 0, bad = 0, p = start;
    while (ok == 0 || bad == 0) {
        if (trial(p)) { ok = p; p *= 1.5; } else { bad = p; p /= 1.5; }
        if (p < start / 64 || p > start * 64) break;
    }
    for (int k = 0; k < 7 && ok > 0 && bad > 0; ++k) {
        p = std::sqrt(ok * bad);
        (trial(p) ? ok : bad) = p;
    }
    Tuned t{trials[0], false, int(trials.size())};
    for (const Trial& x : trials)
        if (x.max_cm <= target_cm && (!t.met || x.bytes < t.best.bytes)) { t.best = x; t.met = true; }
    if (!t.met)
        for (const Trial& x : trials)
            if (x.max_cm < t.best.max_cm) t.best = x;
    return t;
}

struct AclSubject {
    double target_cm = 0;
    std::string precisions_file;
    std::vector<float> precision;
    std::vector<AclClip> clips;
    size_t bytes = 0;
    double max_cm = 0, world_max_cm = 0;
    uint32_t met = 0;
    std::vector<double> compress_cpu_s;  // per rep, whole library
    std::vector<std::unique_ptr<Context>> ctx;  // 1 + kTickInstances
    std::vector<int64_t> bound;  // clip each context is initialised for, -1 none
};

// Reads clip,precision,... rows (the CSV `tune` writes) in the dump's clip order.
std::vector<float> read_precisions(const std::string& path, const Clips& set) {
    FILE* f = std::fopen(path.c_str(), "r");
    if (!f) fail("%s: cannot open", path.c_str());
    std::map<std::string, float> by_name;
    char line[1024];
    while (std::fgets(line, sizeof line, f)) {
        char* comma = std::strchr(line, ',');
        if (!comma || std::strncmp(line, "clip,", 5) == 0) continue;
        *comma = 0;
        by_name[line] = std::strtof(comma + 1, nullptr);
    }
    std::fclose(f);
    std::vector<float> out;
    for (const Clip& c : set.clips) {
        auto it = by_name.find(c.name);
        if (it == by_name.end() || !(it->second > 0)) fail("%s: no precision for clip %s", path.c_str(), c.name.c_str());
        out.push_back(it->second);
    }
    return out;
}

void bind(AclSubject& a, uint32_t instance, uint32_t clip) {
    if (a.bound[instance] == int64_t(clip)) return;
    if (!a.ctx[instance]->initialize(*a.clips[clip].tracks)) std::abort();
    a.bound[instance] = clip;
}

// Local to world in place, parents first (ACL has no such step; this is ours). It composes what
// MCD_SAMPLE_WORLD composes: rotation and translation, and from format 2 on scale too.
#if MCD_FORMAT_MAJOR >= 2
constexpr const char* kAclCompose = "rtm::qvv_mul";
inline rtm::qvvf compose(const rtm::qvvf& local, const rtm::qvvf& parent) { return rtm::qvv_mul(local, parent); }
#else
constexpr const char* kAclCompose = "rtm::qvv_mul_no_scale";
inline rtm::qvvf compose(const rtm::qvvf& local, const rtm::qvvf& parent) { return rtm::qvv_mul_no_scale(local, parent); }
#endif

inline void acl_to_world(const std::vector<int32_t>& parents) {
    const uint32_t n = uint32_t(parents.size());
    for (uint32_t i = 0; i < n; ++i)
        if (parents[i] >= 0) g_acl_pose[i] = compose(g_acl_pose[i], g_acl_pose[parents[i]]);
}

PassTime pass_acl(AclSubject& a, const std::vector<Step>& steps, const std::vector<int32_t>* parents, bool world) {
    PoseWriter writer(g_acl_pose);
    a.bound[0] = -1;  // sequential and random passes initialise instance 0 per clip, inside the timing
    const double c0 = cpu_s(), w0 = wall_s();
    for (const Step& s : steps) {
        bind(a, s.instance, s.clip);
        Context& ctx = *a.ctx[s.instance];
        ctx.seek(s.time, acl::sample_rounding_policy::none);
        ctx.decompress_tracks(writer);
        if (world) acl_to_world(parents[s.clip]);
        consume(g_acl_pose);
    }
    const double dc = cpu_s() - c0, dw = wall_s() - w0;
    return {dc * 1e6 / double(steps.size()), dw * 1e6 / double(steps.size())};
}
// The world path that is timed, checked once at every frame.
double acl_world_error(AclSubject& a, const Clips& set) {
    PoseWriter writer(g_acl_pose);
    Context ctx;
    double worst = 0;
    for (size_t c = 0; c < set.clips.size(); ++c) {
        const Clip& k = set.clips[c];
        if (!ctx.initialize(*a.clips[c].tracks)) std::abort();
        for (uint32_t f = 0; f < k.frames; ++f) {
            ctx.seek(float(f) / k.rate_f, acl::sample_rounding_policy::none);
            ctx.decompress_tracks(writer);
            acl_to_world(k.parents);
            float xyz[kMaxNodes * 3];
            for (uint32_t i = 0; i < k.nodes; ++i) {
                xyz[3 * i] = rtm::vector_get_x(g_acl_pose[i].translation);
                xyz[3 * i + 1] = rtm::vector_get_y(g_acl_pose[i].translation);
                xyz[3 * i + 2] = rtm::vector_get_z(g_acl_pose[i].translation);
            }
            worst = std::max(worst, world_error_cm(k, f, xyz, 3, set.cm_per_unit));
        }
    }
    return worst;
}
#endif  // MCD_BENCH_ACL

// ------------------------------------------------------------------------------------ JSON
struct Json {
    FILE* f;
    bool first = true;
    void raw(const char* s) { std::fputs(s, f); }
    void sep() { if (!first) raw(", "); first = false; }
    void key(const char* k) { sep(); str(k); raw(": "); first = true; }
    void str(const std::string& s) {
        std::fputc('"', f);
        for (char ch : s) {
            if (ch == '"' || ch == '\\') std::fputc('\\', f);
            if (uint8_t(ch) < 0x20) std::fprintf(f, "\\u%04x", ch); else std::fputc(ch, f);
        }
        std::fputc('"', f);
    }
    void num(double v) { if (std::isfinite(v)) std::fprintf(f, "%.9g", v); else raw("null"); }
    void open(char c) { sep(); std::fputc(c, f); first = true; }
    void close(char c) { std::fputc(c, f); first = false; }
    void kv(const char* k, double v) { key(k); num(v); first = false; }
    void kv(const char* k, const std::string& v) { key(k); str(v); first = false; }
    void kvb(const char* k, bool v) { key(k); raw(v ? "true" : "false"); first = false; }
    void summary(const char* k, const std::vector<double>& v) {
        const Summary s = summarize(v);
        key(k); open('{');
        kv("median", s.median); kv("p25", s.p25); kv("p75", s.p75); kv("min", s.min); kv("max", s.max);
        close('}');
    }
    void array(const char* k, const std::vector<double>& v) {
        key(k); open('[');
        for (double x : v) { sep(); num(x); }
        close(']');
    }
};

// ---------------------------------------------------------------------------------- tune
int cmd_tune(int argc, char** argv) {
    if (argc < 1) fail("tune: give the clip dump");
    std::string dump = argv[0], out;
    double target = 0;
    float shell = 3.0F;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 >= argc) fail("tune: %s needs a value", a.c_str());
        if (a == "--target-cm") target = std::atof(argv[++i]);
        else if (a == "--shell") shell = float(std::atof(argv[++i]));
        else if (a == "--out") out = argv[++i];
        else fail("tune: unknown option %s", a.c_str());
    }
    if (!(target > 0) || out.empty()) fail("tune: give --target-cm E and --out FILE");
#if MCD_BENCH_ACL
    const Clips set = read_dump(dump);
    FILE* f = std::fopen(out.c_str(), "w");
    if (!f) fail("%s: cannot write", out.c_str());
    std::fprintf(f, "clip,precision,bytes,max_cm,met,trials\n");
    size_t bytes = 0;
    for (const Clip& c : set.clips) {
        const Tuned t = tune_clip(c, target, set.cm_per_unit, shell);
        std::fprintf(f, "%s,%.9g,%u,%.6f,%d,%d\n", c.name.c_str(), t.best.precision, t.best.bytes, t.best.max_cm,
                     int(t.met), t.trials);
        std::fprintf(stderr, "  %s: precision %.6g, %u bytes, max %.4f cm%s\n", c.name.c_str(), t.best.precision,
                     t.best.bytes, t.best.max_cm, t.met ? "" : " (target not met: lowest error kept)");
        bytes += t.best.bytes;
    }
    std::fclose(f);
    std::fprintf(stderr, "ACL at max <= %g cm: %zu bytes\n", target, bytes);
    return 0;
#else
    (void)shell;
    fail("tune: this build has no ACL (compile with -DMCD_BENCH_ACL=1 and ACL's includes)");
#endif
}

// ----------------------------------------------------------------------------------- run
int cmd_run(int argc, char** argv) {
    if (argc < 1) fail("run: give the clip dump");
    const std::string dump = argv[0];
    std::string json_path, no_acl_reason;
    int rounds = 11, compress_reps = 3, open_reps = 21;
    float shell = 3.0F;
    std::vector<std::pair<double, std::string>> acl_args;
    std::vector<std::pair<std::string, std::string>> mcd_args;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 >= argc) fail("run: %s needs a value", a.c_str());
        const std::string v = argv[++i];
        const size_t eq = v.find('=');
        if (a == "--rounds") rounds = std::atoi(v.c_str());
        else if (a == "--compress-reps") compress_reps = std::atoi(v.c_str());
        else if (a == "--open-reps") open_reps = std::atoi(v.c_str());
        else if (a == "--json") json_path = v;
        else if (a == "--shell") shell = float(std::atof(v.c_str()));
        else if (a == "--no-acl") no_acl_reason = v;
        else if (a == "--acl" && eq != std::string::npos) acl_args.push_back({std::atof(v.substr(0, eq).c_str()), v.substr(eq + 1)});
        else if (a == "--mcd" && eq != std::string::npos) mcd_args.push_back({v.substr(0, eq), v.substr(eq + 1)});
        else fail("run: bad option %s %s (see the top of engine_bench.cpp)", a.c_str(), v.c_str());
    }
    if (json_path.empty() || rounds < 1 || compress_reps < 1 || open_reps < 1) fail("run: give --json OUT and positive counts");
#if !MCD_BENCH_ACL
    (void)shell, (void)compress_reps;
    if (!acl_args.empty()) fail("run: --acl given but this build has no ACL");
    if (no_acl_reason.empty()) no_acl_reason = "the driver was built without ACL";
#endif
    const Clips set = read_dump(dump);
    std::vector<std::pair<uint32_t, float>> lengths;
    std::vector<std::vector<int32_t>> parents;
    for (const Clip& c : set.clips) { lengths.push_back({c.frames, c.rate_f}); parents.push_back(c.parents); }
    Workloads w = make_workloads(lengths);

    // mocodec assets: open, map clips, error check.
    std::vector<std::unique_ptr<McdSubject>> mcd;
    for (const auto& [label, path] : mcd_args) {
        auto m = std::make_unique<McdSubject>();
        m->label = label;
        const size_t colon = label.find(':');
        m->codec = label.substr(0, colon);
        m->tolerance_cm = colon == std::string::npos ? NAN : std::atof(label.c_str() + colon + 1);
        open_mcd(*m, path);
        map_clips(*m, set);
        m->max_cm = mcd_max_error(*m, set);
        m->world_max_cm = mcd_world_error(*m, set);
        std::fprintf(stderr, "mocodec %s: %zu bytes, max %.4f cm (float world path %.4f)\n", label.c_str(), m->bytes.n,
                     m->max_cm, m->world_max_cm);
        mcd.push_back(std::move(m));
    }

#if MCD_BENCH_ACL
    // ACL: compress at the tuned precisions (timed: the throughput), check the error.
    std::vector<std::unique_ptr<AclSubject>> acl;
    for (const auto& [target, file] : acl_args) {
        auto a = std::make_unique<AclSubject>();
        a->target_cm = target;
        a->precisions_file = file;
        a->precision = read_precisions(file, set);
        a->clips.resize(set.clips.size());
        for (int rep = 0; rep < compress_reps; ++rep) {
            double seconds = 0;
            for (size_t c = 0; c < set.clips.size(); ++c) {
                AclClip out;
                seconds += compress(set.clips[c], a->precision[c], shell, out);
                if (rep == 0) a->clips[c] = std::move(out);
            }
            a->compress_cpu_s.push_back(seconds);
        }
        for (size_t c = 0; c < set.clips.size(); ++c) {
            const double e = acl_max_error(set.clips[c], *a->clips[c].tracks, set.cm_per_unit);
            a->max_cm = std::max(a->max_cm, e);
            a->met += e <= target;
            a->bytes += a->clips[c].tracks->get_size();
        }
        a->world_max_cm = acl_world_error(*a, set);
        for (int k = 0; k <= kTickInstances; ++k) a->ctx.push_back(std::make_unique<Context>());
        a->bound.assign(1 + kTickInstances, -1);
        for (int k = 0; k < kTickInstances; ++k) bind(*a, uint32_t(1 + k), w.tick_clips[k]);
        std::fprintf(stderr, "ACL %g cm: %zu bytes, max %.4f cm (float world path %.4f), %u of %zu clips met, "
                     "compress %.2f s CPU\n", target, a->bytes, a->max_cm, a->world_max_cm, a->met, set.clips.size(),
                     summarize(a->compress_cpu_s).median);
        acl.push_back(std::move(a));
    }
#endif

    // Open: interleaved repetitions.
    std::vector<std::vector<Timer>> mcd_timers;
    for (auto& m : mcd) mcd_timers.push_back(mcd_open_timers(*m));
#if MCD_BENCH_ACL
    std::vector<std::vector<Timer>> acl_timers;
    for (auto& a : acl) {
        AclSubject* s = a.get();
        std::vector<Timer> ts;
        ts.emplace_back("init", [s] {
                          Context ctx;
                          for (const AclClip& c : s->clips) {
                              const acl::compressed_tracks* t = acl::make_compressed_tracks(c.tracks);
                              if (!t || !ctx.initialize(*t)) std::abort();
                              consume(&ctx);
                          }
                      });
        ts.emplace_back("validate", [s] {
                          for (const AclClip& c : s->clips)
                              if (c.tracks->is_valid(true).any()) std::abort();
                      });
        acl_timers.push_back(std::move(ts));
    }
#endif
    auto each_timer = [&](const std::function<void(Timer&)>& fn) {
#if MCD_BENCH_ACL
        for (auto& ts : acl_timers) for (Timer& t : ts) fn(t);
#endif
        for (auto& ts : mcd_timers) for (Timer& t : ts) fn(t);
    };
    each_timer([](Timer& t) { calibrate(t, 300.0); });
    for (int r = 0; r < open_reps; ++r) each_timer(time_once);

    // Decode: rounds of (mode, subject) passes; round -1 warms up.
    struct Subject { int acl = -1, mcd = -1; };
    std::vector<Subject> subjects;
#if MCD_BENCH_ACL
    for (size_t k = 0; k < acl.size(); ++k) subjects.push_back({int(k), -1});
#endif
    for (size_t k = 0; k < mcd.size(); ++k) subjects.push_back({-1, int(k)});
    const size_t ns = subjects.size(), nm = sizeof kModes / sizeof kModes[0];
    std::vector<std::vector<std::vector<PassTime>>> times(nm, std::vector<std::vector<PassTime>>(ns));
    for (int r = -1; r < rounds; ++r) {
        std::fprintf(stderr, r < 0 ? "warm-up round\n" : "round %d of %d\n", r + 1, rounds);
        for (size_t mi = 0; mi < nm; ++mi) {
            const Mode& mode = kModes[mi];
            const std::vector<Step>& steps = w.*mode.steps;
            for (size_t j = 0; j < ns; ++j) {
                const size_t si = (j + size_t(std::max(r, 0)) + mi) % ns;  // rotate the order
                PassTime t;
#if MCD_BENCH_ACL
                if (subjects[si].acl >= 0) t = pass_acl(*acl[subjects[si].acl], steps, parents.data(), mode.world);
                else
#endif
                    t = pass_mcd(*mcd[subjects[si].mcd], steps, mode.world);
                if (r >= 0) times[mi][si].push_back(t);
            }
        }
    }

    // ------------------------------------------------------------------------- report
    FILE* f = std::fopen(json_path.c_str(), "w");
    if (!f) fail("%s: cannot write", json_path.c_str());
    Json j{f};
    j.open('{');
    j.kv("clips", double(set.clips.size()));
    j.kv("frames", double(set.frames));
    j.kv("nodes_total", double(set.node_frames));
    j.kv("raw_acl_bytes", double(set.raw_acl_bytes));
    j.kv("raw_bvh_bytes", double(set.raw_bvh_bytes));
    j.kv("cm_per_unit", set.cm_per_unit);
    j.kv("rounds", rounds);
    char seed[32];
    std::snprintf(seed, sizeof seed, "%#" PRIx64, kSeed);
    j.kv("seed", std::string(seed));
    j.key("runtime"); j.open('{');
    j.kv("format_major", MCD_FORMAT_MAJOR); j.kv("version", double(mcd_version())); j.kv("cflags", MCD_BENCH_RUNTIME_FLAGS);
    j.close('}');
    j.key("tick"); j.open('{');
    j.kv("instances", kTickInstances); j.kv("hz", kTickHz); j.kv("ticks", w.ticks);
    j.key("clips"); j.open('[');
    for (uint32_t c : w.tick_clips) { j.sep(); j.str(set.clips[c].name); }
    j.close(']');
    j.close('}');
    j.key("modes"); j.open('[');
    for (const Mode& m : kModes) {
        j.open('{'); j.kv("key", std::string(m.key)); j.kv("label", std::string(m.label));
        j.kv("poses", double((w.*m.steps).size())); j.close('}');
    }
    j.close(']');
    j.key("acl"); j.open('{');
#if MCD_BENCH_ACL
    j.kvb("available", no_acl_reason.empty());
    j.kv("reason", no_acl_reason);
    j.kv("context_bytes", double(sizeof(Context)));
    j.kv("world_compose", kAclCompose);
    j.kv("compress_reps", compress_reps);
    j.kv("shell_units", shell);
    j.key("targets"); j.open('[');
    for (auto& a : acl) {
        j.open('{');
        j.kv("target_cm", a->target_cm); j.kv("bytes", double(a->bytes)); j.kv("max_cm", a->max_cm);
        j.kv("world_path_max_cm", a->world_max_cm);
        j.kv("clips_met", a->met); j.kvb("all_met", a->met == set.clips.size());
        j.kv("engine_bytes_1", double(a->bytes + sizeof(Context)));
        j.kv("engine_bytes_tick", double(a->bytes + kTickInstances * sizeof(Context)));
        j.summary("compress_cpu_s", a->compress_cpu_s);
        j.kv("precisions_file", a->precisions_file);
        j.close('}');
    }
    j.close(']');
#else
    j.kvb("available", false);
    j.kv("reason", no_acl_reason);
#endif
    j.close('}');
    j.key("mcd"); j.open('[');
    for (auto& m : mcd) {
        const size_t held = m->bytes.n + m->resident.n;
        j.open('{');
        j.kv("label", m->label); j.kv("codec", m->codec); j.kv("tolerance_cm", m->tolerance_cm);
        j.kv("asset_bytes", double(m->bytes.n)); j.kv("resident_bytes", double(m->resident.n));
        j.kv("scratch_bytes", double(m->scratch_bytes)); j.kv("max_cm", m->max_cm);
        j.kv("world_path_max_cm", m->world_max_cm);
        j.kv("engine_bytes_1", double(held + m->scratch_bytes));
        j.kv("engine_bytes_tick", double(held + kTickInstances * m->scratch_bytes));
        j.close('}');
    }
    j.close(']');
    auto timers_json = [&j](const std::vector<Timer>& ts) {
        j.key("times_us"); j.open('{');
        for (const Timer& t : ts) j.summary(t.name.c_str(), t.us);
        j.close('}');
        j.key("repeat"); j.open('{');
        for (const Timer& t : ts) j.kv(t.name.c_str(), t.repeat);
        j.close('}');
    };
    j.key("open"); j.open('[');
#if MCD_BENCH_ACL
    for (size_t k = 0; k < acl.size(); ++k) {
        j.open('{'); j.kv("subject", "acl"); j.kv("target_cm", acl[k]->target_cm); j.kv("clips", double(set.clips.size()));
        timers_json(acl_timers[k]); j.close('}');
    }
#endif
    for (size_t k = 0; k < mcd.size(); ++k) {
        j.open('{'); j.kv("subject", mcd[k]->label); timers_json(mcd_timers[k]); j.close('}');
    }
    j.close(']');
    j.key("speed"); j.open('[');
    for (size_t si = 0; si < ns; ++si) {
        const bool is_acl = subjects[si].acl >= 0;
        double tol = NAN;
#if MCD_BENCH_ACL
        if (is_acl) tol = acl[subjects[si].acl]->target_cm;
#endif
        if (!is_acl) tol = mcd[subjects[si].mcd]->tolerance_cm;
        int ref = -1;  // the ACL subject of the same tolerance
        for (size_t k = 0; k < ns && !is_acl; ++k) {
#if MCD_BENCH_ACL
            if (subjects[k].acl >= 0 && acl[subjects[k].acl]->target_cm == tol) ref = int(k);
#endif
        }
        j.open('{');
        j.kv("subject", is_acl ? std::string("acl") : mcd[subjects[si].mcd]->label);
        j.kv("tolerance_cm", tol);
        j.key("modes"); j.open('{');
        for (size_t mi = 0; mi < nm; ++mi) {
            std::vector<double> cpu, wall, ratio;
            for (size_t r = 0; r < times[mi][si].size(); ++r) {
                cpu.push_back(times[mi][si][r].cpu_us);
                wall.push_back(times[mi][si][r].wall_us);
                if (ref >= 0) ratio.push_back(times[mi][si][r].cpu_us / times[mi][size_t(ref)][r].cpu_us);
            }
            j.key(kModes[mi].key); j.open('{');
            j.summary("cpu_us", cpu); j.summary("wall_us", wall); j.array("per_round_cpu_us", cpu);
            if (ref >= 0) j.summary("ratio", ratio);
            j.close('}');
        }
        j.close('}');
        j.close('}');
    }
    j.close(']');
    j.close('}');
    std::fputc('\n', f);
    if (std::fclose(f) != 0) fail("%s: write failed", json_path.c_str());
    return 0;
}

// --------------------------------------------------------------------------------- speed
// mocodec alone on one asset: median over `runs` passes of µs per pose (thread CPU), local and
// world, every frame in order and as many uniform random times.
int cmd_speed(int argc, char** argv) {
    if (argc < 1) fail("usage: engine_bench speed ASSET.mcd [runs] [local-seq|local-rand|world-seq|world-rand]");
    const int runs = argc > 1 ? std::atoi(argv[1]) : 15;
    const std::string only = argc > 2 ? argv[2] : "";
    if (runs < 1) fail("speed: runs must be positive");
    McdSubject m;
    m.label = argv[0];
    open_mcd(m, argv[0]);
    std::vector<std::pair<uint32_t, float>> lengths;
    size_t frames = 0;
    for (uint32_t c = 0; c < mcd_clip_count(&m.asset); ++c) {
        mcd_clip_info info;
        mcd_get_clip_info(&m.asset, c, &info);
        lengths.push_back({info.frame_count, info.frame_rate});
        m.clip_map.push_back(c);
        frames += info.frame_count;
    }
    Workloads w = make_workloads(lengths);
    const struct { const char* name; const std::vector<Step>* steps; bool world; } modes[4] = {
        {"local-seq", &w.sequential, false}, {"local-rand", &w.random, false},
        {"world-seq", &w.sequential, true}, {"world-rand", &w.random, true}};
    double median[4] = {NAN, NAN, NAN, NAN};
    for (int k = 0; k < 4; ++k) {
        if (!only.empty() && only != modes[k].name) continue;
        std::vector<double> us;
        for (int r = 0; r < runs; ++r) us.push_back(pass_mcd(m, *modes[k].steps, modes[k].world).cpu_us);
        median[k] = quantile(us, 0.5);
    }
    Json j{stdout};
    j.open('{');
    j.kv("asset_bytes", double(m.bytes.n)); j.kv("resident_bytes", double(m.resident.n));
    j.kv("scratch_bytes", double(m.scratch_bytes)); j.kv("clips", double(lengths.size()));
    j.kv("frames", double(frames)); j.kv("runs", runs); j.kv("clock", "thread_cpu");
    j.kv("runtime_cflags", MCD_BENCH_RUNTIME_FLAGS);
    j.kv("us_per_pose_local_sequential", median[0]); j.kv("us_per_pose_local_random", median[1]);
    j.kv("us_per_pose_world_sequential", median[2]); j.kv("us_per_pose_world_random", median[3]);
    j.close('}');
    std::fputc('\n', stdout);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: engine_bench tune|run|speed ... (see the top of bench/engine_bench.cpp)\n");
        return 2;
    }
    try {
        const std::string cmd = argv[1];
        if (cmd == "tune") return cmd_tune(argc - 2, argv + 2);
        if (cmd == "run") return cmd_run(argc - 2, argv + 2);
        if (cmd == "speed") return cmd_speed(argc - 2, argv + 2);
        std::fprintf(stderr, "engine_bench: unknown command %s\n", cmd.c_str());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "engine_bench: %s\n", e.what());
        return 1;
    }
}
