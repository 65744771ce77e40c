#pragma once
// The state dump (JSON Lines, README "Using it") and the state hash. Both walk the world in a fixed order:
// entities by ascending slot, and for each the state codecs in registration order, so two runs of the same
// scenario give the same lines and the same hashes.

#include "engine/catalog.h"
#include "engine/world.h"

#include <cstdint>
#include <string>

namespace tumble {

/// Appends one dump line (with its newline): {"frame", "t", "hash", "entities": {name: {"kind", ...}}}.
void appendDumpLine(std::string& out, const World& world, const Catalog& catalog, std::uint64_t frame,
                    double t, std::uint64_t hash);

/// Whether some state codec claims the entity (the dump lists it).
bool claimed(const World& world, const Catalog& catalog, Entity e);
/// Writes an entity's object of the dump: {"kind": the first codec's kind, its fields, then, for each other
/// codec that claims the entity (a body that is also an emitter), its kind: {its fields}}. Nothing for an
/// entity no codec claims.
void dumpEntity(JsonWriter& w, const World& world, const Catalog& catalog, Entity e);

/// 64-bit hash of every simulated byte in the world (every codec's bytes, entity by entity). `pool`
/// (optional) hashes long arrays on its workers, with the same result (engine/hash.h).
std::uint64_t stateHash(const World& world, const Catalog& catalog, WorkerPool* pool = nullptr);

/// The hash of one entity's simulated state.
std::uint64_t entityHash(const World& world, const Catalog& catalog, Entity e, WorkerPool* pool = nullptr);

/// "0x" followed by 16 hex digits.
std::string hashHex(std::uint64_t h);

/// A dump line made strict JSON: the bare words NaN, Infinity and -Infinity it writes for non-finite
/// numbers (which JSON has no spelling for) quoted, so that a JSON parser reads them as strings.
std::string quoteNonFinite(std::string line);

} // namespace tumble
