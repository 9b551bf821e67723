// Calls into a plugin after its trial load, guarded (plugin_guard.hpp): the
// thread-local chain of calls in flight, the watchdog, the fault handling
// the crash handler (output.cpp) defers to, and the plugins' objects named
// at exit. What the signal handlers read is in fixed tables of plain data;
// they call only async-signal-safe functions (write, _exit, siglongjmp),
// and backtrace(), loaded beforehand (install_plugin_guard).
#include <hz/core/plugin_guard.hpp>

#include "plugin_internal.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <execinfo.h>
#include <link.h>
#include <pthread.h>
#include <signal.h>
#include <string>
#include <thread>
#include <ucontext.h>
#include <unistd.h>

namespace hz::core {

namespace {

thread_local PluginCallSite *tl_site = nullptr;

std::atomic<bool> g_installed{false};
std::atomic<bool> g_disabled{false};
std::atomic<double> g_timeout_s{10.0};

// The watchdog's table: one slot per timed call in flight (and one for the
// exit), the thread to interrupt and when.
constexpr int kWatchSlots = 64;
// (`fired` is true whenever the slot watches nothing: the watchdog skips
// it; a claim sets the deadline and the thread first, then clears it)
struct Slot {
    std::atomic<bool> used{false};
    std::atomic<bool> fired{true};
    std::atomic<bool> expired{false};  // the watchdog interrupted the call (set with `fired`)
    std::atomic<std::int64_t> deadline_ns{0};
    pthread_t thread{};
};
Slot g_slots[kWatchSlots];
std::atomic<bool> g_watchdog{false};
constexpr int kSignal = SIGUSR2;

// At exit: the command's status, and the slot watching the exit.
std::atomic<bool> g_exiting{false};
std::atomic<int> g_exit_status{0};

// The plugins' objects: address ranges (their PT_LOAD segments' span) and files.
constexpr int kObjects = 64;
constexpr std::size_t kFileMax = 1024;
struct Object {
    std::uintptr_t lo = 0, hi = 0;
    char file[kFileMax] = {};
};
Object g_objects[kObjects];
std::atomic<int> g_object_count{0};

std::int64_t now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void tell(const char *s) { detail::write_stderr(s); }

const char *signal_name(int sig) {
    switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGABRT: return "SIGABRT";
    default: return "a signal";
    }
}

void watch_calls() {
    for (;;) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        const std::int64_t now = now_ns();
        for (Slot &s : g_slots) {
            if (!s.used.load() || s.fired.load() || s.deadline_ns.load() > now) continue;
            s.fired.store(true);
            s.expired.store(true);
            ::pthread_kill(s.thread, kSignal);
        }
    }
}

int claim_slot(double timeout_s) {
    if (!g_watchdog.exchange(true)) std::thread(watch_calls).detach();
    for (int i = 0; i < kWatchSlots; ++i) {
        bool expected = false;
        if (!g_slots[i].used.compare_exchange_strong(expected, true)) continue;
        g_slots[i].deadline_ns.store(now_ns() + std::int64_t(timeout_s * 1e9));
        g_slots[i].thread = ::pthread_self();
        g_slots[i].expired.store(false);
        g_slots[i].fired.store(false);
        return i;
    }
    return -1;  // (64 timed calls at once: this one is not timed)
}

// The plugin file whose code holds `pc`, or null.
const char *object_at(std::uintptr_t pc) {
    const int n = g_object_count.load();
    for (int i = 0; i < n && i < kObjects; ++i)
        if (pc >= g_objects[i].lo && pc < g_objects[i].hi) return g_objects[i].file;
    return nullptr;
}

// The plugin file whose code this thread is in (the faulting instruction,
// else the innermost plugin frame on its stack), or null.
const char *plugin_on_stack(void *ucontext) {
    const std::uintptr_t pc = detail::fault_pc(ucontext);
    if (const char *f = pc ? object_at(pc) : nullptr) return f;
    void *frames[64];
    const int n = ::backtrace(frames, 64);
    for (int i = 0; i < n; ++i)
        if (const char *f = object_at(std::uintptr_t(frames[i]))) return f;
    return nullptr;
}

// The innermost call in flight on this thread, if a fault returns into it
// (an inner call that is not recoverable owns the fault).
PluginCallSite *recoverable() { return tl_site != nullptr && tl_site->recover ? tl_site : nullptr; }

// The watchdog's signal: a timed call past its deadline on this thread
// returns into its guard; at exit, a plugin's destructor that holds the
// process up ends it.
void on_watchdog(int, siginfo_t *, void *ucontext) {
    for (PluginCallSite *s = tl_site; s != nullptr; s = s->outer) {
        if (s->slot < 0 || !g_slots[s->slot].expired.load()) continue;
        if (s->recover) {
            s->fault = -1;
            siglongjmp(s->env, 1);
        }
    }
    if (!g_exiting.load()) return;  // (a call that just returned)
    const char *file = plugin_on_stack(ucontext);
    if (file == nullptr) return;  // (not held up by a plugin: exiting goes on)
    tell("horizon: warning: the plugin ");
    tell(file);
    tell(
        " did not let the process end (its destructors ran past the plugin timeout) after the command had finished; "
        "move it out of the plugin folders or report it to its author\n");
    ::_exit(g_exit_status.load());
}

}  // namespace

std::uintptr_t detail::fault_pc(void *ucontext) {
#if defined(__x86_64__)
    if (ucontext) return std::uintptr_t(static_cast<ucontext_t *>(ucontext)->uc_mcontext.gregs[REG_RIP]);
#elif defined(__aarch64__)
    if (ucontext) return std::uintptr_t(static_cast<ucontext_t *>(ucontext)->uc_mcontext.pc);
#endif
    return 0;
}

void enter_plugin_call(PluginCallSite &s) {
    s.fault = 0;
    s.outer = tl_site;
    s.slot = -1;
    if (s.timeout_s > 0 && g_installed.load() && !g_disabled.load()) s.slot = claim_slot(s.timeout_s);
    tl_site = &s;
}

void leave_plugin_call(PluginCallSite &s) {
    if (s.slot >= 0) g_slots[s.slot].fired.store(true), g_slots[s.slot].used.store(false), s.slot = -1;
    tl_site = s.outer;
}

std::string fault_text(const PluginCallSite &s) {
    if (s.fault == -1) return std::string("did not return from ") + s.call + "() within " + std::to_string(int(s.timeout_s + 0.5)) + " s";
    return std::string("crashed (") + signal_name(s.fault) + ") in " + s.call + "()";
}

PluginCallMark::PluginCallMark(const char *plugin, const char *call) {
    site_.plugin = plugin;
    site_.call = call;
    enter_plugin_call(site_);
}

PluginCallMark::~PluginCallMark() { leave_plugin_call(site_); }

void set_plugin_call_timeout(double seconds) { g_timeout_s.store(seconds); }
double plugin_call_timeout() { return g_timeout_s.load(); }

void register_plugin_object(const void *address, const std::string &file) {
    struct Find {
        std::uintptr_t at, lo = 0, hi = 0;
    } find{std::uintptr_t(address)};
    ::dl_iterate_phdr(
        [](dl_phdr_info *info, std::size_t, void *data) {
            auto &f = *static_cast<Find *>(data);
            std::uintptr_t lo = UINTPTR_MAX, hi = 0;
            for (int i = 0; i < info->dlpi_phnum; ++i) {
                const auto &ph = info->dlpi_phdr[i];
                if (ph.p_type != PT_LOAD) continue;
                lo = std::min<std::uintptr_t>(lo, info->dlpi_addr + ph.p_vaddr);
                hi = std::max<std::uintptr_t>(hi, info->dlpi_addr + ph.p_vaddr + ph.p_memsz);
            }
            if (f.at < lo || f.at >= hi) return 0;
            f.lo = lo, f.hi = hi;
            return 1;
        },
        &find);
    if (find.hi == 0) return;
    static std::atomic<int> claimed{0};
    const int i = claimed.fetch_add(1);
    if (i >= kObjects) return;
    Object &o = g_objects[i];
    o.lo = find.lo, o.hi = find.hi;
    std::strncpy(o.file, file.c_str(), kFileMax - 1);
    g_object_count.store(i + 1);  // (the handlers read the entry once it is whole)
}

void install_plugin_guard() {
    // An alternate stack for this thread's fault handlers (a plugin that
    // overflows its stack), and backtrace() loaded now, not in a handler.
    static char stack[1 << 16];
    stack_t ss{};
    ss.ss_sp = stack;
    ss.ss_size = sizeof stack;
    (void)::sigaltstack(&ss, nullptr);
    void *frames[2];
    (void)::backtrace(frames, 2);
    struct sigaction sa {};
    sa.sa_sigaction = on_watchdog;
    sa.sa_flags = SA_SIGINFO | SA_ONSTACK | SA_RESTART;  // (a stray interrupt of a system call is restarted, not an EINTR)
    sigemptyset(&sa.sa_mask);
    ::sigaction(kSignal, &sa, nullptr);
    g_installed.store(true);
}

bool plugin_guard_installed() { return g_installed.load() && !g_disabled.load(); }

void disable_plugin_guard() { g_disabled.store(true); }

bool plugin_fault(int sig, void *ucontext) {
    if (!plugin_guard_installed()) return false;
    if (PluginCallSite *s = recoverable()) {
        s->fault = sig;
        siglongjmp(s->env, 1);
    }
    const PluginCallSite *s = tl_site;
    const char *file = s != nullptr ? s->plugin : plugin_on_stack(ucontext);
    if (file == nullptr) return false;
    if (g_exiting.load()) {
        tell("horizon: warning: the plugin ");
        tell(file);
        tell(" crashed (");
        tell(signal_name(sig));
        tell(
            ") at exit, after the command had finished (its exit status stands); move it out of the plugin folders or report it "
            "to its author\n");
        ::_exit(g_exit_status.load());
    }
    tell("horizon: error: the plugin ");
    tell(file);
    tell(" crashed (");
    tell(signal_name(sig));
    if (s != nullptr) {
        tell(") in ");
        tell(s->call);
        tell("(");
    }
    tell("); move it out of the plugin folders or report it to its author\n");
    return true;
}

void plugins_at_exit(int status) {
    g_exit_status.store(status);
    g_exiting.store(true);
    if (!plugin_guard_installed() || g_object_count.load() == 0) return;
    // (a slot of no call: the watchdog interrupts this thread at the
    // deadline, and on_watchdog looks for a plugin on its stack)
    (void)claim_slot(g_timeout_s.load());
}

}  // namespace hz::core
