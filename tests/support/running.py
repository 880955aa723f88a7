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


def signal_keeps_earlier_file(proc, out, folder, signum, earlier):
    """For a run started by start_until_temporary that writes out (holding earlier): its
    temporary file is there, out stays as it was while the run goes on, and signum ends
    the program by the signal, with out unchanged and no temporary file left."""
    assert temporary_files(folder) == ["%s.%d.tmp" % (out.name, proc.pid)]
    time.sleep(0.5)  # paces the check only
    assert out.read_bytes() == earlier
    proc.send_signal(signum)
    proc.communicate(timeout=60)
    assert proc.returncode == -signum  # ended by the signal
    assert out.read_bytes() == earlier
    assert temporary_files(folder) == []
