// Not a verb: registered like one so that main() installs the interrupt handlers before any
// verb runs (core/io/interrupt_cleanup.h): SIGINT/SIGTERM/SIGHUP remove the hidden temporaries
// of the files being written, then end the process as the signal would.
#include "core/io/interrupt_cleanup.h"
#include "tools/verb.h"

BODYMODEL_VERB(install_interrupt_cleanup_at_startup) { bodymodel::install_interrupt_cleanup(); }
