"""Running one Blender render process for the data-set drivers (render_dataset.py, render_shots.py): its output
appended to a log, in a process group of its own so that a timeout or an interruption ends Blender and all it
started."""
import os
import signal
import subprocess


def run_logged(cmd, log_path, timeout, header, mode="a"):
    """Runs CMD with stdout and stderr into LOG_PATH (HEADER written first); its exit status, or None when it ran
    past TIMEOUT seconds (killed)."""
    os.makedirs(os.path.dirname(log_path), exist_ok=True)
    with open(log_path, mode) as logf:
        logf.write(header)
        logf.flush()
        proc = subprocess.Popen(cmd, stdout=logf, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return None
        except BaseException:  # Ctrl-C, or the driver stopped: Blender goes too
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            raise
