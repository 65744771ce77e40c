// Fuzz target: the replay reader. Every chunk of a replay is checksummed, so random bytes are almost all
// turned away at the first checksum; to reach what lies behind them, inputs whose first byte is even have
// their checksums recomputed (header, chunks, end marker) before they are read. Odd ones are read as they
// are, so that the checks themselves are fuzzed too.

#include "engine/replay.h"
#include "tests/fuzz/fuzz_support.h"

#include <cstring>

namespace {

std::uint32_t u32At(const std::string& b, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, b.data() + at, 4);
    return v;
}

void putChecksum(std::string& b, std::size_t payloadAt, std::size_t n) {
    const std::uint64_t sum = tumble::replayChecksum(b.substr(payloadAt, n));
    std::memcpy(b.data() + payloadAt + n, &sum, 8);
}

/// Rewrites every checksum the framing can reach (the layout is in engine/replay.h).
void fixChecksums(std::string& b) {
    if (b.size() < 16) {
        return;
    }
    std::size_t at = 16;
    const std::size_t header = u32At(b, 12);
    if (header > b.size() - at || b.size() - at - header < 8) {
        return;
    }
    putChecksum(b, at, header);
    at += header + 8;
    while (b.size() - at >= 12) {
        if (std::memcmp(b.data() + at, "ENDR", 4) == 0) {
            if (b.size() - at >= 20) {
                putChecksum(b, at + 4, 8);
            }
            return;
        }
        const std::uint32_t n = u32At(b, at + 4);
        const std::uint32_t notN = ~n;
        std::memcpy(b.data() + at + 8, &notN, 4);
        if (n > b.size() - at - 12 || b.size() - at - 12 - n < 8) {
            return;
        }
        putChecksum(b, at + 12, n);
        at += 12 + std::size_t(n) + 8;
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace tumble;
    if (size == 0) {
        return 0;
    }
    std::string bytes = fuzz::text(data + 1, size - 1);
    if (data[0] % 2 == 0) {
        fixChecksums(bytes);
    }
    try {
        parseReplay("fuzzed.tumble", bytes);
    } catch (const ReplayError&) {
    }
    return 0;
}
