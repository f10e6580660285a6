# Sourced by the test scripts: `apt_need PACKAGE...` installs the Debian packages given (the caller
# lists only the missing ones) when it can (root with apt-get); returns 1, saying so, when it cannot.
apt_need() {
  [ $# -gt 0 ] || return 0
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "== installing $* (apt)"
    apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null && return 0
    echo "!! apt-get could not install $*" >&2
  else
    echo "!! missing $* and cannot install them (not root or no apt)" >&2
  fi
  return 1
}
