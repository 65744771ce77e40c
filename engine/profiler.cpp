#include "engine/profiler.h"

#include "engine/json.h"
#include "engine/parallel.h"

#include <algorithm>
#include <cmath>

namespace tumble {

void Profiler::Ring::push(float ms, std::size_t capacity) {
    if (samples.size() < capacity) {
        samples.push_back(ms);
        return;
    }
    samples[next] = ms;
    next = (next + 1) % capacity;
}

double Profiler::Ring::percentile(double p) const {
    if (samples.empty()) {
        return 0.0;
    }
    // nearest rank on a sorted copy; only done when statistics are asked for
    std::vector<float> sorted(samples);
    std::sort(sorted.begin(), sorted.end());
    const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size())));
    return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

Profiler::Profiler(std::size_t ringCapacity)
    : m_origin(TimeSource::now()), m_capacity(std::max<std::size_t>(ringCapacity, 1)) {
    m_physics.samples.reserve(m_capacity);
    m_render.samples.reserve(m_capacity);
    m_critical.samples.reserve(m_capacity);
}

int Profiler::addSlot(std::string name, Phase phase, bool isPhase) {
    std::lock_guard lock(m_mutex);
    return addSlotLocked(std::move(name), phase, isPhase);
}

int Profiler::addSlotLocked(std::string name, Phase phase, bool isPhase) {
    Slot s{std::move(name), phase, isPhase, {}, 0, 0, 0, {}};
    s.recent.samples.reserve(m_capacity);
    m_slots.push_back(std::move(s));
    return static_cast<int>(m_slots.size() - 1);
}

int Profiler::stageSlot(std::string_view name, Phase phase) {
    std::lock_guard lock(m_mutex);
    for (std::size_t i = 0; i < m_slots.size(); ++i) {
        if (!m_slots[i].isPhase && m_slots[i].name == name) {
            return static_cast<int>(i);
        }
    }
    const int slot = addSlotLocked(std::string(name), phase, false);
    m_slots[std::size_t(slot)].stageOf = std::string(name.substr(0, name.find('.')));
    return slot;
}

int Profiler::counterSlot(std::string_view name) {
    std::lock_guard lock(m_mutex);
    for (std::size_t i = 0; i < m_counters.size(); ++i) {
        if (m_counters[i].name == name) {
            return static_cast<int>(i);
        }
    }
    m_counters.push_back({std::string(name)});
    return static_cast<int>(m_counters.size() - 1);
}

void Profiler::count(int counter, double value) noexcept {
    std::lock_guard lock(m_mutex);
    CounterStats& c = m_counters[static_cast<std::size_t>(counter)];
    c.max = c.samples == 0 ? value : std::max(c.max, value);
    ++c.samples;
    c.nonzero += value != 0.0;
    c.last = value;
}

void Profiler::beginFrame(std::uint64_t frame) {
    std::lock_guard lock(m_mutex);
    m_frame = frame;
    m_frameStartNs = nowNs();
    m_framePhysicsNs = 0;
    m_frameRenderNs = 0;
    m_frameCriticalNs = 0;
}

void Profiler::endFrame() {
    std::lock_guard lock(m_mutex);
    const std::int64_t end = nowNs();
    ++m_frames;
    m_physics.push(static_cast<float>(static_cast<double>(m_framePhysicsNs) * 1e-6), m_capacity);
    m_render.push(static_cast<float>(static_cast<double>(m_frameRenderNs) * 1e-6), m_capacity);
    m_critical.push(static_cast<float>(static_cast<double>(m_frameCriticalNs) * 1e-6), m_capacity);
    m_physicsMaxNs = std::max(m_physicsMaxNs, m_framePhysicsNs);
    if (m_framePhysicsNs > m_budgetNs) {
        ++m_overBudget;
    }
    keepTraceEvent({-1, 0, m_frame, m_frameStartNs, end - m_frameStartNs});
}

std::vector<float> Profiler::Ring::last(std::size_t n) const {
    n = std::min(n, samples.size());
    std::vector<float> out(n);
    // the newest sample sits just before `next` (at the end while the ring fills, when next is 0)
    const std::size_t end = next == 0 ? samples.size() : next;
    for (std::size_t k = 0; k < n; ++k) {
        out[n - 1 - k] = samples[(end + samples.size() - 1 - k) % samples.size()];
    }
    return out;
}

std::vector<RecentSlot> Profiler::recentStats(std::size_t n) const {
    std::lock_guard lock(m_mutex);
    std::vector<RecentSlot> out;
    for (const Slot& s : m_slots) {
        const std::vector<float> last = s.recent.last(n);
        double sum = 0.0;
        for (float ms : last) {
            sum += ms;
        }
        out.push_back({s.name, s.phase, s.isPhase, last.empty() ? 0.0 : sum / double(last.size())});
    }
    return out;
}

std::vector<float> Profiler::recentPhysics(std::size_t n) const {
    std::lock_guard lock(m_mutex);
    return m_physics.last(n);
}

std::vector<float> Profiler::physicsHistory() const {
    std::lock_guard lock(m_mutex);
    const auto& r = m_physics;
    if (r.samples.size() < m_capacity) {
        return r.samples;
    }
    std::vector<float> out(r.samples.begin() + std::ptrdiff_t(r.next), r.samples.end());
    out.insert(out.end(), r.samples.begin(), r.samples.begin() + std::ptrdiff_t(r.next));
    return out;
}

void Profiler::keepTraceEvent(const TraceEvent& e) noexcept {
    if (!m_trace || m_traceTruncated) {
        return;
    }
    if (m_events.size() >= kMaxTraceEvents) {
        m_traceTruncated = true;
        return;
    }
    try {
        m_events.push_back(e);
    } catch (const std::bad_alloc&) {
        m_traceTruncated = true;
    }
}

void Profiler::addCriticalPath(std::int64_t ns) noexcept {
    std::lock_guard lock(m_mutex);
    m_frameCriticalNs += ns;
}

void Profiler::record(int slot, std::int64_t startNs, std::int64_t durationNs) noexcept {
    std::lock_guard lock(m_mutex);
    Slot& s = m_slots[std::size_t(slot)];
    ++s.calls;
    s.sumNs += durationNs;
    s.maxNs = std::max(s.maxNs, durationNs);
    s.recent.push(static_cast<float>(static_cast<double>(durationNs) * 1e-6), m_capacity);
    if (s.isPhase) {
        if (s.phase == Phase::Fixed) {
            m_framePhysicsNs += durationNs;
        } else if (s.phase == Phase::Frame) {
            m_frameRenderNs += durationNs;
        }
    }
    keepTraceEvent({slot, WorkerPool::threadIndex(), m_frame, startNs, durationNs});
}

std::vector<SlotStats> Profiler::slotStats() const {
    std::lock_guard lock(m_mutex);
    // in slot order, each system's stages right after it (stages are made on first use, after every system)
    std::vector<const Slot*> order;
    for (const Slot& s : m_slots) {
        if (!s.stageOf.empty()) {
            continue;
        }
        order.push_back(&s);
        for (const Slot& stage : m_slots) {
            if (stage.stageOf == s.name && !s.isPhase) {
                order.push_back(&stage);
            }
        }
    }
    for (const Slot& s : m_slots) {
        if (!s.stageOf.empty() && std::find(order.begin(), order.end(), &s) == order.end()) {
            order.push_back(&s); // a stage of no system of this profiler
        }
    }
    std::vector<SlotStats> out;
    out.reserve(m_slots.size());
    for (const Slot* slot : order) {
        const Slot& s = *slot;
        SlotStats st;
        st.name = s.name;
        st.phase = s.phase;
        st.isPhase = s.isPhase;
        // a stage of no system is listed on its own, under its whole name (not as a stage of the row above)
        const bool orphan = std::none_of(m_slots.begin(), m_slots.end(), [&](const Slot& owner) {
            return owner.stageOf.empty() && !owner.isPhase && owner.name == s.stageOf;
        });
        st.stageOf = orphan ? std::string() : s.stageOf;
        st.calls = s.calls;
        st.meanMs = s.calls ? static_cast<double>(s.sumNs) * 1e-6 / static_cast<double>(s.calls) : 0.0;
        st.maxMs = static_cast<double>(s.maxNs) * 1e-6;
        // the ring keeps float milliseconds, the maximum whole nanoseconds: rounded to float, the largest
        // sample can come out above the maximum (25,328,500 ns is 25.3285007 ms in float)
        st.p50Ms = std::min(s.recent.percentile(0.50), st.maxMs);
        st.p99Ms = std::min(s.recent.percentile(0.99), st.maxMs);
        out.push_back(std::move(st));
    }
    return out;
}

FrameStats Profiler::frameStats() const {
    std::lock_guard lock(m_mutex);
    FrameStats f;
    f.frames = m_frames;
    f.physicsMaxMs = static_cast<double>(m_physicsMaxNs) * 1e-6;
    // no percentile above the maximum (the ring's float rounding; see slotStats)
    f.physicsP50Ms = std::min(m_physics.percentile(0.50), f.physicsMaxMs);
    f.physicsP99Ms = std::min(m_physics.percentile(0.99), f.physicsMaxMs);
    f.criticalP50Ms = m_critical.percentile(0.50);
    f.criticalP99Ms = m_critical.percentile(0.99);
    f.renderP50Ms = m_render.percentile(0.50);
    f.overBudgetFrames = m_overBudget;
    return f;
}

void Profiler::writeTrace(std::ostream& out) const {
    std::lock_guard lock(m_mutex);
    std::string buf;
    JsonWriter w(buf);
    w.beginObject().key("displayTimeUnit").value("ms").key("traceEvents").beginArray();
    // name the process and each thread's track so Perfetto labels them: the caller's, then the workers'
    int tracks = 1;
    for (const TraceEvent& e : m_events) {
        tracks = std::max(tracks, e.track + 1);
    }
    auto meta = [&](const char* what, int tid, const std::string& name) {
        w.beginObject().key("name").value(what).key("ph").value("M").key("pid").value(1).key("tid").value(
            tid);
        w.key("args").beginObject().key("name").value(name).endObject().endObject();
    };
    meta("process_name", 1, "tumble");
    meta("thread_name", 1, "simulation");
    for (int t = 1; t < tracks; ++t) {
        meta("thread_name", t + 1, "worker " + std::to_string(t));
    }
    for (const TraceEvent& e : m_events) {
        w.beginObject();
        if (e.slot < 0) {
            w.key("name").value("frame").key("cat").value("frame");
        } else {
            const Slot& s = m_slots[std::size_t(e.slot)];
            w.key("name").value(s.name).key("cat").value(s.isPhase ? "phase" : phaseName(s.phase));
        }
        // trace timestamps are microseconds
        w.key("ph").value("X").key("ts").value(static_cast<double>(e.startNs) * 1e-3);
        w.key("dur").value(static_cast<double>(e.durationNs) * 1e-3).key("pid").value(1);
        w.key("tid").value(e.track + 1);
        w.key("args").beginObject().key("frame").value(e.frame).endObject();
        w.endObject();
        if (buf.size() > (1u << 16)) {
            out << buf;
            buf.clear();
        }
    }
    if (m_traceTruncated) {
        // an instant event at the end of what was kept says why the trace stops there
        const double at = m_events.empty() ? 0.0 : static_cast<double>(m_events.back().startNs) * 1e-3;
        w.beginObject().key("name").value("trace truncated: event limit reached").key("ph").value("i");
        w.key("s").value("g").key("ts").value(at).key("pid").value(1).key("tid").value(1).endObject();
    }
    w.endArray().endObject();
    buf += '\n';
    out << buf;
}

} // namespace tumble
