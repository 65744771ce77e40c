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
        // the first codec that claims the entity gives its kind
        for (const StateCodec& codec : catalog.states()) {
            if (codec.has(world, e)) {
                w.key(name->value).beginObject().key("kind").value(codec.kind);
                codec.dump(world, e, w);
                w.endObject();
                break;
            }
        }
    }
    w.endObject().endObject();
    out += '\n';
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
