# Sourced first thing by the scripts of tools/ (not run): with -h or --help as the first argument,
# prints the script's header comment, its usage, and exits.
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then
  awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"
  exit 0
fi
