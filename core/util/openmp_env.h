// OpenMP's wait policy for programs that run oneDNN.
//
// Debian's oneDNN runs its threads on OpenMP (libgomp). By default libgomp's idle threads spin for a while
// before they sleep; on a machine shared with other processes (a render farm node, a desktop) two spinning
// threads per parallel region make inference several times slower and steal the others' cores.
// OMP_WAIT_POLICY=passive makes them sleep at once, but libgomp reads it only when it is loaded, before
// main() runs, so setting it from inside the program is too late: the program has to start again.
#pragma once

namespace residue {

// If OMP_WAIT_POLICY is not set, sets it to "passive" and re-executes this program (/proc/self/exe) with
// the same arguments; returns only when nothing needs doing or the re-execution failed (then the program
// goes on with OpenMP's default policy). A user's own OMP_WAIT_POLICY is left alone. Call it first in main().
void ensure_passive_openmp(int argc, char** argv);

}  // namespace residue
