#include "engine/dump.h"

#include "engine/name.h"

#include <cstdio>
#include <string_view>

namespace tumble {

void appendDumpLine(std::string& out, const World& world, const Catalog& catalog, std::uint64_t frame,
                    double t, std::uint64_t hash) {
    JsonWriter w(out);
    w.beginObject().key("frame").value(frame).key("t").value(t).key("hash").value(hashHex(hash));
    w.key("entities").beginObject();
    for (Entity e : world.entities()) {
        const Name* name = world.tryGet<Name>(e);
        if (!name) {
            continue;
        }
        if (claimed(world, catalog, e)) {
            w.key(name->value);
            dumpEntity(w, world, catalog, e);
        }
    }
    w.endObject().endObject();
    out += '\n';
}

bool claimed(const World& world, const Catalog& catalog, Entity e) {
    for (const StateCodec& codec : catalog.states()) {
        if (codec.has(world, e)) {
            return true;
        }
    }
    return false;
}

void dumpEntity(JsonWriter& w, const World& world, const Catalog& catalog, Entity e) {
    // the first codec that claims the entity gives its kind and its fields; any other one (a body that is
    // also an emitter) its fields in an object of their own, under its kind
    bool first = true;
    for (const StateCodec& codec : catalog.states()) {
        if (!codec.has(world, e)) {
            continue;
        }
        if (first) {
            w.beginObject().key("kind").value(codec.kind);
        } else {
            w.key(codec.kind).beginObject();
        }
        codec.dump(world, e, w);
        if (!first) {
            w.endObject();
        }
        first = false;
    }
    if (!first) {
        w.endObject();
    }
}

std::uint64_t entityHash(const World& world, const Catalog& catalog, Entity e, WorkerPool* pool) {
    Hasher h(pool);
    h.add(e.index);
    for (const StateCodec& codec : catalog.states()) {
        if (codec.has(world, e)) {
            codec.hash(world, e, h);
        }
    }
    return h.digest();
}

std::uint64_t stateHash(const World& world, const Catalog& catalog, WorkerPool* pool) {
    Hasher h;
    for (Entity e : world.entities()) {
        h.add(entityHash(world, catalog, e, pool));
    }
    return h.digest();
}

std::string hashHex(std::uint64_t h) {
    char buf[20];
    std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(h));
    return buf;
}

std::string quoteNonFinite(std::string line) {
    for (const std::string_view word : {"-Infinity", "Infinity", "NaN"}) {
        for (std::size_t at = 0; (at = line.find(word, at)) != std::string::npos;) {
            // a bare word is a value: it follows '[', ',' or ':' (spaces aside), never a letter, a quote or
            // the minus of a -Infinity already quoted
            std::size_t before = at;
            while (before > 0 && line[before - 1] == ' ') {
                --before;
            }
            if (before > 0 && std::string_view("[,:").find(line[before - 1]) != std::string_view::npos) {
                line.replace(at, word.size(), "\"" + std::string(word) + "\"");
                at += 2;
            }
            at += word.size();
        }
    }
    return line;
}

} // namespace tumble
