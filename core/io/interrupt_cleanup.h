// Clean interruption of a process that writes files through write_atomically
// (core/io/atomic_write.h).
//
// write_atomically already guarantees that no file under its final name is ever partial: it
// writes ".<name>.tmp<pid>_<n>" beside it and renames only a complete file. What an interrupt
// could leave behind is that hidden temporary. install_interrupt_cleanup() makes SIGINT, SIGTERM
// and SIGHUP remove the temporaries this process has open, then end the process with the
// signal's default action (so a shell sees 128 + signal: 130 for Ctrl-C, 143 for kill).
// The handler uses async-signal-safe system calls only (open, getdents64, readlink, unlink,
// sigaction, raise): it lists /proc/self/fd and unlinks every open file whose name is a
// write_atomically temporary of this process. Linux only (elsewhere the handler just
// re-raises, leaving at most a hidden temporary, still never a partial final file).
#pragma once

namespace bodymodel {

// Installs the handlers; idempotent. A signal that was ignored when the process started
// (nohup, background jobs of a non-interactive shell) stays ignored.
void install_interrupt_cleanup();

// True when `filename` (no folder) is a write_atomically temporary of process `pid`:
// ".<final name>.tmp<pid>_<digits>". Allocation-free (the signal handler uses it).
bool is_atomic_write_temporary(const char* filename, long pid);

// Removes the write_atomically temporaries this process has open right now (what the handler
// does before re-raising); returns how many it removed. Async-signal-safe.
int remove_open_temporaries();

}  // namespace bodymodel
