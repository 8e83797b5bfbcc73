#!/usr/bin/env python3
"""tests/pty_session.py - drives an interactive program through a pseudo-terminal, as a user
at a terminal would (readline, Ctrl-C as the terminal's SIGINT), for the console tests.

usage: pty_session.py [--timeout S] -- COMMAND... ::: STEP...
Steps (run in order; the first that fails ends the session with exit status 1):
  send:TEXT        type TEXT and Enter
  type:TEXT        type TEXT without Enter
  intr             press Ctrl-C (the terminal sends SIGINT to the program)
  expect:REGEX     wait until the output since the last expect matches REGEX
  sleep:SECONDS
  file:PATH:TEXT   the file PATH contains TEXT now
  exit:CODE        wait for the program to end with exit status CODE
  dump             write the transcript so far to stderr
The whole transcript is written to stderr when a step fails.
"""
import os
import pty
import re
import select
import sys
import time


def main():
    args = sys.argv[1:]
    timeout = 60.0
    if args[:1] == ["--timeout"]:
        timeout = float(args[1])
        args = args[2:]
    if args[:1] == ["--"]:
        args = args[1:]
    sep = args.index(":::")
    command, steps = args[:sep], args[sep + 1:]
    pid, fd = pty.fork()
    if pid == 0:
        os.execvp(command[0], command)
    transcript = b""
    mark = 0  # expect matches output after this offset

    def read_some(wait):
        nonlocal transcript
        ready, _, _ = select.select([fd], [], [], wait)
        if not ready:
            return True
        try:
            data = os.read(fd, 65536)
        except OSError:
            return False
        if not data:
            return False
        transcript += data
        return True

    def fail(why):
        sys.stderr.write("pty_session: %s\n--- transcript ---\n%s\n--- end ---\n"
                         % (why, transcript.decode("utf-8", "replace")))
        try:
            os.kill(pid, 9)
        except OSError:
            pass
        sys.exit(1)

    for step in steps:
        kind, _, arg = step.partition(":")
        if kind in ("send", "type"):
            os.write(fd, (arg + ("\r" if kind == "send" else "")).encode())
        elif kind == "intr":
            os.write(fd, b"\x03")
        elif kind == "sleep":
            end = time.time() + float(arg)
            while time.time() < end:
                read_some(max(0.0, end - time.time()))
        elif kind == "expect":
            pattern = re.compile(arg.encode())
            end = time.time() + timeout
            while True:
                m = pattern.search(transcript, mark)
                if m:
                    mark = m.end()
                    break
                if time.time() > end:
                    fail("timed out waiting for %r" % arg)
                if not read_some(0.2):
                    if not pattern.search(transcript, mark):
                        fail("program ended before %r" % arg)
        elif kind == "file":
            path, _, text = arg.partition(":")
            try:
                content = open(path).read()
            except OSError as e:
                fail("cannot read %s: %s" % (path, e))
            if text not in content:
                fail("%s does not contain %r: %r" % (path, text, content))
        elif kind == "exit":
            end = time.time() + timeout
            while read_some(0.2):
                if time.time() > end:
                    fail("program did not end")
            _, status = os.waitpid(pid, 0)
            code = os.waitstatus_to_exitcode(status)
            if code != int(arg):
                fail("exit status %d, expected %s" % (code, arg))
            return 0
        elif kind == "dump":
            read_some(0.2)
            sys.stderr.write(transcript.decode("utf-8", "replace") + "\n")
        else:
            fail("unknown step %r" % step)
    os.kill(pid, 9)
    os.waitpid(pid, 0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
