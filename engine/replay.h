#pragma once
// Replay files (README, "Replays"): what a run needs to be played again bit for bit, and what it must
// give when it is. Binary, little-endian:
//
//   header   "TUMBLERP", u32 format version, u32 n, n bytes of header payload, u64 checksum of the payload
//            payload: the build id, the scenario's path (for messages) and text, the --set overrides
//   chunks   "CHNK", u32 n, u32 ~n, n bytes of payload, u64 checksum of the payload; one every
//            kFramesPerChunk frames, flushed, so a crash or a kill leaves every chunk but the last whole
//            payload: u64 first frame, u32 frames, u32 names declared here, each (u32 id, name, kind);
//            then per frame: u32 events, each (u64 step, entity, action, u32 k, k f64 value, 3 f64
//            position, f64 radius, f64 amount, set); u64 state hash; u32 entities, each (u32 id, u64 hash)
//   end      "ENDR", u64 frames, u64 checksum of those 8 bytes: the recording finished
//
// Strings are u32 length + bytes. Every chunk's payload is checksummed and its length is written twice (the
// second inverted), so one flipped byte anywhere is caught and located, and a file cut short is told
// apart from a damaged one: it replays up to its last whole chunk. The per-entity hashes name the entity
// whose state diverged.

#include "engine/catalog.h"
#include "engine/scene.h"
#include "engine/world.h"
#include "tumble/errors.h"

#include <cstdint>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace tumble {

/// One entity's state hash after a frame.
struct EntityHash {
    std::string name; ///< when written; a replay as read keeps names once, in ReplayFile::names
    std::string kind; ///< the dump kind(s) of its components, '+'-joined
    std::uint64_t hash = 0;
    std::uint32_t id = 0; ///< as read: the index of its name and kind in ReplayFile::names
};

/// What happened in one frame: the events applied at its steps, and the state it left.
struct FrameRecord {
    std::vector<EventDef> events;
    std::uint64_t hash = 0;
    std::vector<EntityHash> entities;
};

/// The scenario a replay was recorded from.
struct ReplayHeader {
    std::uint32_t version = 0;
    std::string buildId;
    std::string scenarioPath;
    std::string scenarioText;
    std::vector<std::string> overrides;
};

/// A replay as read: its header and every whole frame in it.
struct ReplayFile {
    ReplayHeader header;
    std::vector<FrameRecord> frames;
    std::vector<std::pair<std::string, std::string>> names; ///< entity name and kind, by id
    bool complete = false;                                  ///< ended with the end marker
    std::uint64_t validBytes = 0;                           ///< bytes up to the last whole chunk
    std::uint64_t fileBytes = 0;
};

/// Goes up whenever the simulated bits or the layout change (2: the multicolour smoother of large cloths; 3:
/// the implicit solver's rows summed in two partials for its AVX2 kernels, keyed particle births, the `set`
/// event's KEY=VALUE in every event; 4: fem bodies' rotations started from their spin, their system blocks
/// summed in float; 5: fem elements two at a time in their own arithmetic; 6: every hash and checksum on
/// XXH3-64; 7: the implicit solver's levels of 1024 rows or more swept colour by colour, its dot products
/// in chunks of 512 rows; 8: particles' ages counted in whole steps, not summed in float; 9: implicit Euler's
/// first guess combined from its last three solutions; 10: its springs' terms kept as two coefficients; 11:
/// the air's dot products in eight running sums a row; 12: fem nodes resting on static bodies held in the
/// implicit solve, air sources fed after the advection; 13: fem box meshes mirrored cell by cell; 14: an air
/// grid's smoke and heat carried by finite volumes; 15: their MacCormack limiter bounded by the box's cells
/// alone; 16-19: air and fem changes, README "Replays"; 20: the air's multigrid smoothed with Chebyshev's
/// weights, its coarse levels weighed 2.2 times the level above, its first guess carried on from the last two
/// pressures; 21: spring networks' masses float in water, its force on them hashed, and particles fall in;
/// 22: a volume met on the water's outermost cells spread by the nodes' shares of a cell),
/// so that another version's replay is refused with a message rather than failing to verify. When it goes up,
/// bash tests/fuzz/make_replay_seeds.sh writes the replay fuzzer's seeds again (a test says so).
inline constexpr std::uint32_t kReplayVersion = 22;
inline constexpr std::uint32_t kFramesPerChunk = 8;

/// This program's build id, as written into replays.
const char* buildId();

/// Writes a replay as a run goes; every chunk is flushed when it is full.
class ReplayWriter {
public:
    /// Opens the file and writes the header (throws ReplayError when the file cannot be written).
    ReplayWriter(const std::string& path, const ReplayHeader& header);
    ~ReplayWriter();
    ReplayWriter(const ReplayWriter&) = delete;
    ReplayWriter& operator=(const ReplayWriter&) = delete;

    /// Adds one frame.
    void frame(const FrameRecord& record);
    /// Writes what is pending and the end marker, and closes the file.
    void finish();

    const std::string& path() const { return m_path; }
    std::uint64_t frames() const { return m_frames; }

private:
    void flushChunk();

    std::string m_path;
    std::FILE* m_file = nullptr;
    std::string m_chunk; ///< frames not yet written
    std::string m_names; ///< names declared in this chunk
    std::uint32_t m_chunkFrames = 0;
    std::uint32_t m_chunkNames = 0;
    std::uint64_t m_frames = 0;
    std::map<std::string, std::uint32_t> m_ids; ///< entity name -> id
};

/// Reads a whole replay; throws ReplayError for a damaged file (a file cut short is not damaged: it ends
/// at its last whole chunk, with complete = false), one that is not a regular file, or one above 1 GiB.
ReplayFile readReplay(const std::string& path);

/// The same, from the file's bytes: `path` is what messages call it.
ReplayFile parseReplay(const std::string& path, const std::string& bytes);

/// The checksum the header, each chunk's payload and the end marker's count carry.
std::uint64_t replayChecksum(const std::string& bytes);

/// The state hash and, for every named entity with simulated state, its own hash. `pool` (optional) hashes
/// long arrays on its workers, with the same result.
std::uint64_t frameHashes(const World& world, const Catalog& catalog, std::vector<EntityHash>& entities,
                          WorkerPool* pool = nullptr);

} // namespace tumble
