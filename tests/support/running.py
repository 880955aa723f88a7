"""Helpers of the end-to-end tests that start a long `mbdae` run and act on it while it
goes on (signals, the earlier results file kept until the run ends)."""
import subprocess
import time


def temporary_files(folder):
    """Names of the temporary results files (`RESULTS.PID.tmp`) in folder, sorted."""
    return sorted(p.name for p in folder.glob("*.tmp"))


def start_until_temporary(args, folder, cwd=None, attempts=600):
    """Starts args and returns the process once a temporary results file exists in folder
    (the run is then under way). Fails the test if the process ends first or no file
    appears in attempts polls of 0.1 s (the sleep only paces the polling)."""
    proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    for _ in range(attempts):
        if temporary_files(folder) or proc.poll() is not None:
            break
        time.sleep(0.1)
    assert proc.poll() is None, proc.communicate()
    return proc
