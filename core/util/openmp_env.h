// OpenMP's wait policy for programs that run oneDNN.
//
// Debian's oneDNN runs its threads on OpenMP (libgomp). By default libgomp's idle threads spin for a while
// before they sleep; on a machine shared with other processes (a render farm node, a desktop) two spinning
// threads per parallel region make inference several times slower and steal the others' cores.
// OMP_WAIT_POLICY=passive makes them sleep at once, but libgomp reads it only when it is loaded, before
// main() runs. So a program that links this file sets it even earlier: from the executable's .preinit_array,
// which the dynamic loader runs before any shared library's initialiser (libgomp's included). That costs
// nothing; the previous way, starting the program a second time, cost a whole process start (0.2 s: Debian's
// OpenImageIO brings 262 shared libraries).
#pragma once

namespace residue {

// Returns at once when OMP_WAIT_POLICY was in place before libgomp started (set by the user, who is left alone,
// or by the pre-initialiser). Only where the pre-initialiser did not run (a loader without .preinit_array)
// does it set the variable and re-execute this program (/proc/self/exe) with the same arguments; it returns
// when that fails, and the program goes on with OpenMP's default policy. Call it first in main(): it also
// keeps the pre-initialiser linked in.
void ensure_passive_openmp(int argc, char** argv);

}  // namespace residue
