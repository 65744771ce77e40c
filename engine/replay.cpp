#include "engine/replay.h"

#include "engine/dump.h"
#include "engine/hash.h"
#include "engine/name.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#ifndef TUMBLE_BUILD_ID
#define TUMBLE_BUILD_ID "unknown"
#endif

namespace tumble {

std::uint64_t replayChecksum(const std::string& bytes) {
    return Hasher::of(bytes.data(), bytes.size());
}

namespace {

constexpr auto checksum = replayChecksum;
constexpr char kMagic[8] = {'T', 'U', 'M', 'B', 'L', 'E', 'R', 'P'};
constexpr std::uint32_t kMaxChunkBytes = 1u << 30;
constexpr std::uint64_t kMaxReplayBytes = 1ull << 30;
constexpr std::size_t kMaxNameBytes = 256; ///< entity names are at most 64 characters, kinds a few words

// ---- writing

template <class T>
void put(std::string& out, T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out.append(b, sizeof(T));
}

void putString(std::string& out, const std::string& s) {
    put(out, static_cast<std::uint32_t>(s.size()));
    out += s;
}

void putEvent(std::string& out, const EventDef& ev) {
    put(out, ev.step);
    putString(out, ev.entity);
    putString(out, ev.action);
    put(out, static_cast<std::uint32_t>(ev.value.size()));
    for (double v : ev.value) {
        put(out, v);
    }
    for (double p : ev.position) {
        put(out, p);
    }
    put(out, ev.radius);
    put(out, ev.amount);
    putString(out, ev.set);
}

// ---- reading

/// Reads little-endian values out of a byte range, failing with the file offset of the problem.
class Cursor {
public:
    Cursor(const std::string& file, const std::string& bytes, std::uint64_t base)
        : m_file(file), m_bytes(bytes), m_base(base) {}

    template <class T>
    T get(const char* what) {
        need(sizeof(T), what);
        T v;
        std::memcpy(&v, m_bytes.data() + m_at, sizeof(T));
        m_at += sizeof(T);
        return v;
    }
    std::string string(const char* what) {
        const auto n = get<std::uint32_t>(what);
        need(n, what);
        std::string s = m_bytes.substr(m_at, n);
        m_at += n;
        return s;
    }
    std::uint32_t count(const char* what, std::size_t minBytesEach) {
        const auto n = get<std::uint32_t>(what);
        if (minBytesEach > 0 && n > remaining() / minBytesEach) {
            fail(std::string("the count of ") + what + " (" + std::to_string(n) + ") does not fit the data");
        }
        return n;
    }
    std::size_t remaining() const { return m_bytes.size() - m_at; }
    std::uint64_t offset() const { return m_base + m_at; }
    [[noreturn]] void fail(const std::string& message) const { throw ReplayError(m_file, offset(), message); }

private:
    void need(std::size_t n, const char* what) const {
        if (n > remaining()) {
            fail(std::string("the data ends inside ") + what);
        }
    }

    const std::string& m_file;
    const std::string& m_bytes;
    std::uint64_t m_base;
    std::size_t m_at = 0;
};

/// A recorded number: finite and within the scenario loader's bounds.
double getNumber(Cursor& c, const char* what) {
    const double v = c.get<double>(what);
    if (!std::isfinite(v) || std::abs(v) > 1e9) {
        c.fail(std::string(what) + " is not a finite number within +-1e9");
    }
    return v;
}

EventDef getEvent(Cursor& c) {
    EventDef ev;
    ev.step = c.get<std::uint64_t>("an event's step");
    ev.entity = c.string("an event's entity");
    ev.action = c.string("an event's action");
    const std::uint32_t n = c.count("an event's values", sizeof(double));
    ev.value.resize(n);
    for (double& v : ev.value) {
        v = getNumber(c, "an event's value");
    }
    for (double& p : ev.position) {
        p = getNumber(c, "an event's position");
    }
    ev.radius = getNumber(c, "an event's radius");
    ev.amount = getNumber(c, "an event's amount");
    ev.set = c.string("a set event's KEY=VALUE");
    return ev;
}

} // namespace

ReplayError::ReplayError(const std::string& file, std::uint64_t offset, const std::string& message)
    : std::runtime_error(file + ": at byte " + std::to_string(offset) + ": " + message) {}

const char* buildId() {
    return TUMBLE_BUILD_ID;
}

std::uint64_t frameHashes(const World& world, const Catalog& catalog, std::vector<EntityHash>& entities,
                          WorkerPool* pool) {
    entities.clear();
    Hasher total;
    for (Entity e : world.entities()) {
        const std::uint64_t h = entityHash(world, catalog, e, pool);
        total.add(h);
        const Name* name = world.tryGet<Name>(e);
        if (!name) {
            continue;
        }
        std::string kinds;
        for (const StateCodec& codec : catalog.states()) {
            if (codec.has(world, e)) {
                kinds += (kinds.empty() ? "" : "+") + codec.kind;
            }
        }
        if (!kinds.empty()) {
            entities.push_back({name->value, std::move(kinds), h});
        }
    }
    return total.digest();
}

// ---- ReplayWriter

ReplayWriter::ReplayWriter(const std::string& path, const ReplayHeader& header) : m_path(path) {
    m_file = std::fopen(path.c_str(), "wb");
    if (!m_file) {
        throw std::runtime_error("cannot write the replay " + path + ": " + std::strerror(errno));
    }
    std::string payload;
    putString(payload, header.buildId);
    // a scenario file's path made absolute: what it names beside itself (a mesh) is found from any folder
    // the replay is played in (as typed, 'boat.toml' was looked for in the player's folder)
    std::string scenario = header.scenarioPath;
    std::error_code ec;
    if (!scenario.empty() && std::filesystem::is_regular_file(scenario, ec)) {
        scenario = std::filesystem::absolute(scenario, ec).lexically_normal().string();
    }
    putString(payload, ec ? header.scenarioPath : scenario);
    putString(payload, header.scenarioText);
    put(payload, static_cast<std::uint32_t>(header.overrides.size()));
    for (const std::string& o : header.overrides) {
        putString(payload, o);
    }
    std::string out(kMagic, sizeof kMagic);
    put(out, kReplayVersion);
    put(out, static_cast<std::uint32_t>(payload.size()));
    out += payload;
    put(out, checksum(payload));
    std::fwrite(out.data(), 1, out.size(), m_file);
    std::fflush(m_file);
}

ReplayWriter::~ReplayWriter() {
    if (m_file) {
        flushChunk(); // an unfinished recording keeps what it has, without the end marker
        std::fclose(m_file);
    }
}

void ReplayWriter::frame(const FrameRecord& record) {
    put(m_chunk, static_cast<std::uint32_t>(record.events.size()));
    for (const EventDef& ev : record.events) {
        putEvent(m_chunk, ev);
    }
    put(m_chunk, record.hash);
    put(m_chunk, static_cast<std::uint32_t>(record.entities.size()));
    for (const EntityHash& e : record.entities) {
        auto [it, added] = m_ids.try_emplace(e.name, static_cast<std::uint32_t>(m_ids.size()));
        if (added) {
            put(m_names, it->second);
            putString(m_names, e.name);
            putString(m_names, e.kind);
            ++m_chunkNames;
        }
        put(m_chunk, it->second);
        put(m_chunk, e.hash);
    }
    ++m_chunkFrames;
    ++m_frames;
    if (m_chunkFrames == kFramesPerChunk) {
        flushChunk();
    }
}

void ReplayWriter::flushChunk() {
    if (m_chunkFrames == 0) {
        return;
    }
    std::string payload;
    put(payload, m_frames - m_chunkFrames);
    put(payload, m_chunkFrames);
    put(payload, m_chunkNames);
    payload += m_names;
    payload += m_chunk;
    std::string out = "CHNK";
    put(out, static_cast<std::uint32_t>(payload.size()));
    put(out, ~static_cast<std::uint32_t>(payload.size()));
    out += payload;
    put(out, checksum(payload));
    std::fwrite(out.data(), 1, out.size(), m_file);
    std::fflush(m_file);
    m_chunk.clear();
    m_names.clear();
    m_chunkFrames = m_chunkNames = 0;
}

void ReplayWriter::finish() {
    if (!m_file) {
        return;
    }
    flushChunk();
    std::string end = "ENDR";
    std::string count;
    put(count, m_frames);
    end += count;
    put(end, checksum(count));
    std::fwrite(end.data(), 1, end.size(), m_file);
    const bool ok = std::fflush(m_file) == 0 && !std::ferror(m_file);
    std::fclose(m_file);
    m_file = nullptr;
    if (!ok) {
        throw std::runtime_error("the replay " + m_path + " could not be written completely (disk full?)");
    }
}

// ---- reading

ReplayFile readReplay(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
        throw ReplayError(path, 0,
                          std::filesystem::exists(path, ec) ? "is not a regular file" : "no such file");
    }
    const auto size = std::filesystem::file_size(path, ec);
    if (ec || size > kMaxReplayBytes) {
        throw ReplayError(path, 0, "is larger than a replay may be (1 GiB)");
    }
    if (size == 0) { // nothing to read (and /proc's files, which say 0, may block a read forever)
        return parseReplay(path, "");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw ReplayError(path, 0, "cannot be read");
    }
    std::string bytes(static_cast<std::size_t>(size), '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
    return parseReplay(path, bytes);
}

namespace {

/// The header: magic, version, build, scenario and overrides, checked by its checksum. Returns the offset
/// where the chunks start.
std::uint64_t parseHeader(const std::string& path, const std::string& bytes, ReplayFile& file) {
    Cursor top(path, bytes, 0);
    if (bytes.size() < sizeof kMagic || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) {
        top.fail("not a Tumble replay (it does not start with TUMBLERP)");
    }
    top.get<std::uint64_t>("the magic");
    file.header.version = top.get<std::uint32_t>("the format version");
    if (file.header.version != kReplayVersion) {
        throw ReplayError(path, 8,
                          "format version " + std::to_string(file.header.version) +
                              "; this build reads version " + std::to_string(kReplayVersion) +
                              " (the version goes up when the simulated bits change, so a replay of another "
                              "version cannot verify here: record it again with this build)");
    }
    const auto headerBytes = top.get<std::uint32_t>("the header's length");
    const std::uint64_t headerAt = top.offset();
    if (headerBytes > top.remaining()) {
        top.fail("the header runs past the end of the file");
    }
    const std::string header = bytes.substr(headerAt, headerBytes);
    const std::uint64_t at = headerAt + headerBytes;
    if (bytes.size() - at < 8) {
        throw ReplayError(path, at, "the data ends inside the header's checksum");
    }
    // the checksum before the fields: a damaged length inside the header is reported as damage to the
    // header, not as a string running out wherever the bad length sent the parse
    std::uint64_t sum;
    std::memcpy(&sum, bytes.data() + at, 8);
    if (sum != checksum(header)) {
        throw ReplayError(path, headerAt,
                          "the header is damaged (its checksum does not match: a byte of the header, or of "
                          "its length at byte " +
                              std::to_string(headerAt - 4) + ", has changed)");
    }
    Cursor h(path, header, headerAt);
    file.header.buildId = h.string("the build id");
    file.header.scenarioPath = h.string("the scenario's path");
    file.header.scenarioText = h.string("the scenario");
    const std::uint32_t n = h.count("the overrides", 4);
    for (std::uint32_t i = 0; i < n; ++i) {
        file.header.overrides.push_back(h.string("an override"));
    }
    return at + 8;
}

/// The end marker at `at` ("ENDR", the frame count, its checksum): the file is complete. Cut short inside
/// the marker, it is not, but every chunk before it is whole.
void parseEnd(const std::string& path, const std::string& bytes, std::uint64_t at, ReplayFile& file) {
    const std::size_t left = bytes.size() - at;
    if (left < 20) {
        return;
    }
    if (left > 20) {
        throw ReplayError(path, at + 20, "there are bytes after the end marker");
    }
    const std::string count = bytes.substr(at + 4, 8);
    std::uint64_t frames, check;
    std::memcpy(&frames, count.data(), 8);
    std::memcpy(&check, bytes.data() + at + 12, 8);
    if (check != checksum(count) || frames != file.frames.size()) {
        throw ReplayError(path, at, "the end marker is damaged");
    }
    file.complete = true;
    file.validBytes = bytes.size();
}

/// One chunk's payload: the names it introduces, then its frames (events, hash, entity hashes).
void parseChunk(Cursor& c, ReplayFile& file) {
    const auto first = c.get<std::uint64_t>("the chunk's first frame");
    if (first != file.frames.size()) {
        c.fail("the chunk starts at frame " + std::to_string(first) + ", not " +
               std::to_string(file.frames.size()));
    }
    const std::uint32_t frames = c.count("the chunk's frames", 16);
    const std::uint32_t declared = c.count("the chunk's names", 12);
    for (std::uint32_t i = 0; i < declared; ++i) {
        const auto id = c.get<std::uint32_t>("a name's id");
        if (id != file.names.size()) {
            c.fail("name ids out of order");
        }
        std::string name = c.string("a name");
        std::string kind = c.string("a kind");
        if (name.size() > kMaxNameBytes || kind.size() > kMaxNameBytes) {
            c.fail("an entity's name or kind is longer than any entity's can be");
        }
        file.names.emplace_back(std::move(name), std::move(kind));
    }
    for (std::uint32_t f = 0; f < frames; ++f) {
        FrameRecord rec;
        const std::uint32_t events = c.count("a frame's events", 40);
        for (std::uint32_t k = 0; k < events; ++k) {
            rec.events.push_back(getEvent(c));
        }
        rec.hash = c.get<std::uint64_t>("a frame's hash");
        const std::uint32_t entities = c.count("a frame's entities", 12);
        for (std::uint32_t k = 0; k < entities; ++k) {
            const auto id = c.get<std::uint32_t>("an entity's id");
            if (id >= file.names.size()) {
                c.fail("entity id " + std::to_string(id) + " was never named");
            }
            rec.entities.push_back({{}, {}, c.get<std::uint64_t>("an entity's hash"), id});
        }
        file.frames.push_back(std::move(rec));
    }
    if (c.remaining() != 0) {
        c.fail("a chunk has bytes left over");
    }
}

} // namespace

ReplayFile parseReplay(const std::string& path, const std::string& bytes) {
    if (bytes.size() > kMaxReplayBytes) {
        throw ReplayError(path, 0, "is larger than a replay may be (1 GiB)");
    }
    ReplayFile file;
    file.fileBytes = bytes.size();
    std::uint64_t at = parseHeader(path, bytes, file);
    file.validBytes = at;
    // chunks, each "CHNK", its length twice (the second inverted), the payload and its checksum; a file cut
    // short keeps every whole chunk before the cut
    while (at < bytes.size()) {
        const std::size_t left = bytes.size() - at;
        if (left >= 4 && std::memcmp(bytes.data() + at, "ENDR", 4) == 0) {
            parseEnd(path, bytes, at, file);
            break;
        }
        if (left < 12) {
            const std::size_t n = std::min<std::size_t>(left, 4);
            if (std::memcmp(bytes.data() + at, "CHNK", n) != 0 &&
                std::memcmp(bytes.data() + at, "ENDR", n) != 0) {
                throw ReplayError(path, at, "expected a chunk or the end marker");
            }
            break; // cut short inside a chunk's head or the end marker
        }
        if (std::memcmp(bytes.data() + at, "CHNK", 4) != 0) {
            throw ReplayError(path, at, "expected a chunk or the end marker");
        }
        std::uint32_t n, notN;
        std::memcpy(&n, bytes.data() + at + 4, 4);
        std::memcpy(&notN, bytes.data() + at + 8, 4);
        if (n != ~notN || n > kMaxChunkBytes) {
            throw ReplayError(path, at + 4, "a chunk's length is damaged");
        }
        if (left < 12 + std::uint64_t(n) + 8) {
            break; // cut short inside this chunk: keep what came before
        }
        const std::string payload = bytes.substr(at + 12, n);
        std::uint64_t check;
        std::memcpy(&check, bytes.data() + at + 12 + n, 8);
        if (check != checksum(payload)) {
            throw ReplayError(path, at + 12, "a chunk is damaged (its checksum does not match)");
        }
        Cursor c(path, payload, at + 12);
        parseChunk(c, file);
        at += 12 + std::uint64_t(n) + 8;
        file.validBytes = at;
    }
    return file;
}

} // namespace tumble
