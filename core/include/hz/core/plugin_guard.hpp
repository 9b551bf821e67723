// Calls into a plugin after its trial load, guarded: a crash or a call that
// does not return is named (the plugin, its file, the call) instead of
// killing or hanging the command without a word.
//
// The trial load (plugin_host.hpp, Registry) runs a plugin's init() and
// descriptors in a child process. Everything after it runs in the host:
// - Short calls whose failure the host can survive (init(), the
//   descriptors and get_interface() of a load in the host, probe(),
//   get_interface() for an extension, deinit()) run through guarded_call():
//   a crash (SIGSEGV, SIGBUS, SIGFPE, SIGILL) returns into the guard
//   (sigsetjmp/siglongjmp), and so does a call still running after the
//   plugin timeout (the watchdog thread interrupts it with SIGUSR2). The
//   caller then reports the plugin and never calls it again (its state is
//   unknown: Module::faulted()).
// - Long calls (reads, writes, clustering, shading) are marked with
//   PluginCallMark: a crash in one is still the end of the command (nothing
//   is known of the plugin's state, or of the data it was writing), but its
//   one line names the plugin and the call.
// - At exit (plugins_at_exit()), a plugin's destructors that crash or do not
//   finish within the timeout end the process with the command's own exit
//   status and a warning naming the plugin, instead of a SIGSEGV or a hang
//   after the command's work was done.
// Recovering from a fault is best effort: a plugin that crashed inside the
// C library (holding its allocator's lock) may still stop the process; the
// watchdog then ends it with the plugin named.
// Threading: guards are per thread (a thread-local chain); the watchdog is
// one thread of its own, started at the first timed call.
#pragma once

#include <csetjmp>
#include <string>
#include <utility>

namespace hz::core {

// One call into a plugin in flight on this thread. The strings must live
// as long as the call (the signal handlers read them).
struct PluginCallSite {
    const char *plugin = "";  // what names the plugin: its id and file, or its file
    const char *call = "";    // "probe", "get_interface", ...
    bool recover = false;     // a fault returns into guarded_call() (else: reported, the process ends)
    double timeout_s = 0;     // > 0: the watchdog interrupts the call after this long (recoverable calls)
    // Filled in when the call faulted: the signal, or -1 (timed out).
    volatile int fault = 0;
    sigjmp_buf env{};
    // (the guard's own)
    PluginCallSite *outer = nullptr;
    int slot = -1;
};

void enter_plugin_call(PluginCallSite &s);
void leave_plugin_call(PluginCallSite &s);

// Runs f() (a call into a plugin: no object with a destructor may be alive
// in f's own frame when the plugin is called) as `s`, recoverable. Returns
// true when it returned, false when it crashed or timed out (s.fault says
// which; fault_text(s) says it in words).
template <class F>
[[nodiscard]] bool guarded_call(PluginCallSite &s, F &&f) {
    s.recover = true;
    if (sigsetjmp(s.env, 1) != 0) {
        leave_plugin_call(s);
        return false;
    }
    enter_plugin_call(s);
    std::forward<F>(f)();
    leave_plugin_call(s);
    return true;
}

// "crashed (SIGSEGV) in probe()", "did not return from probe() within 10 s".
std::string fault_text(const PluginCallSite &s);

// A long call into a plugin, for the crash report only (not recoverable, no
// timeout): RAII.
class PluginCallMark {
public:
    PluginCallMark(const char *plugin, const char *call);
    ~PluginCallMark();
    PluginCallMark(const PluginCallMark &) = delete;
    PluginCallMark &operator=(const PluginCallMark &) = delete;

private:
    PluginCallSite site_;
};

// The timeout of recoverable calls (Registry::Options::timeout_s sets it).
void set_plugin_call_timeout(double seconds);
double plugin_call_timeout();

// Remembers where plugin file `file` is mapped (the object holding
// `address`): a crash or a hang at exit in its code is then named.
void register_plugin_object(const void *address, const std::string &file);

// Installed by install_termination_cleanup() (io.hpp): the watchdog's
// signal (SIGUSR2) and an alternate signal stack for this thread. Without
// it, guarded calls run unguarded (a fault kills the process as before).
void install_plugin_guard();
// Whether install_plugin_guard() ran in this process (a child of spawn()
// does not inherit it: its parent watches it).
bool plugin_guard_installed();
// In a forked child: no watchdog, no recovery (the child dies of the real
// signal, and its parent names it).
void disable_plugin_guard();

// Called by the crash handler (output.cpp) on this thread's fault: returns
// into a recoverable call's guard (does not return), or, where the fault is
// in a plugin's call or code, writes one line naming it and returns true
// (at exit: ends the process with the command's status). False: not a
// plugin's.
bool plugin_fault(int sig, void *ucontext);

// The command is done with status `status`: from now on, a plugin's
// destructor that crashes, or does not let the process end within the
// plugin timeout, ends it with this status and a warning naming it.
void plugins_at_exit(int status);

}  // namespace hz::core
