# Sourced by the test scripts: `apt_need PACKAGE...` installs the Debian packages given (the caller
# lists only the missing ones) when it can (root with apt-get); returns 1, saying so, when it cannot.
# The lock (also taken by runtime_c/test_platforms.sh and bindings/run_engine_tests.sh): run_all.sh
# runs two lanes of test scripts at once, and a second apt-get at the same time fails.
MCD_APT_LOCK=/tmp/mocodec-apt.lock
apt_need() {
  [ $# -gt 0 ] || return 0
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "== installing $* (apt)"
    flock "$MCD_APT_LOCK" sh -c 'apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null' apt_need "$@" &&
      return 0
    echo "!! apt-get could not install $*" >&2
  else
    echo "!! missing $* and cannot install them (not root or no apt)" >&2
  fi
  return 1
}
