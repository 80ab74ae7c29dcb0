// The process-wide interrupt flag of long bakes (docs/bake.md, "Interrupting and resuming").
// A signal handler calls requestInterrupt(); work loops poll interruptRequested() between
// chunks and stop (after saving the checkpoint, if any) by throwing prt::Interrupted. The
// library never installs handlers or exits.
#pragma once

namespace prt::bake {

/// Sets the process-wide interrupt flag. Async-signal-safe: meant for signal handlers.
void requestInterrupt(int signal) noexcept;
/// True once requestInterrupt() was called (and until clearInterrupt()).
bool interruptRequested() noexcept;
/// The signal passed to requestInterrupt(), 0 if none.
int interruptSignal() noexcept;
/// Resets the flag (tests; a tool that runs several bakes).
void clearInterrupt() noexcept;

}  // namespace prt::bake
