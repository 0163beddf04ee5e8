# A digest of the setup scripts: .ci/setup writes it into the virtual environment when it
# finishes, and tools/run-tests runs .ci/setup again whenever it is missing or differs.
setup_stamp() {
  cat .ci/setup .ci/setup.d/* 2>/dev/null | sha256sum | cut -d' ' -f1
}
