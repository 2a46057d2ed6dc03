#!/usr/bin/env bash
# Rebuilds each fork in patches/ (patches/NAME/) from its pristine crates.io crate and its
# patch series (patches/NAME.series), and checks that the vendored tree is exactly that.
# See usage() and patches/README.md. Tools: bash, coreutils, curl, tar, patch, diff, sha256sum.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: patches/rebuild.sh [--fork NAME] [--write | --diff | --self-test]

Rebuilds each fork from its pristine crates.io crate and its series file
patches/NAME.series (the crate, its sha256, the paths the vendored copy drops, the diffs
in the order they apply), then compares the result with patches/NAME/ byte for byte.

  (no option)   check only: one line per fork; exit 1, naming every differing file,
                if patches/NAME/ is not exactly pristine + series
  --write       regenerate patches/NAME/ from pristine + series (for maintainers)
  --diff        print what patches/NAME/ has that pristine + series lacks, as a diff in
                the series' format (--- a/PATH, +++ b/PATH, for patch -p1): save it as
                patches/NAME-WHAT.diff and append that name to patches/NAME.series
  --self-test   check that this script catches a changed byte, a stray file and a diff
                that does not apply (on a temporary copy; patches/ is not touched)
  --fork NAME   only this fork (repeatable; default: every patches/*.series)
  -h, --help    this text

The crate is taken from cargo's cache (${CARGO_HOME:-~/.cargo}/registry/cache) or
downloaded once from https://static.crates.io into
${XDG_CACHE_HOME:-~/.cache}/causal-arm/crates; its sha256 must equal the series'.
Works from any directory.
EOF
}

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/causal-arm/crates
CARGO_CACHE=${CARGO_HOME:-$HOME/.cargo}/registry/cache

die() { printf 'rebuild.sh: %s\n' "$*" >&2; exit 1; }

mode=check
forks=()
while (($#)); do
  case $1 in
    --write | --diff | --self-test)
      [[ $mode == check ]] || die "choose one of --write, --diff, --self-test"
      mode=${1#--} ;;
    --fork) (($# >= 2)) || die "--fork needs a NAME"; forks+=("$2"); shift ;;
    --fork=*) forks+=("${1#--fork=}") ;;
    -h | --help) usage; exit 0 ;;
    *) printf 'rebuild.sh: unknown argument %q\n\n' "$1" >&2; usage >&2; exit 2 ;;
  esac
  shift
done
if ((${#forks[@]} == 0)); then
  for s in "$HERE"/*.series; do
    [[ -f $s ]] || die "no series file in $HERE"
    s=${s##*/}
    forks+=("${s%.series}")
  done
fi

TMP=$(mktemp -d "${TMPDIR:-/tmp}/causal-arm-rebuild.XXXXXX")
trap 'rm -rf "$TMP"' EXIT

sha256_of() { local sum _; read -r sum _ < <(sha256sum < "$1"); printf '%s' "$sum"; }

# Reads patches/$1.series into NAME, CRATE, VERSION, SHA, DROPS, IGNORES, DIFFS.
read_series() {
  NAME=$1 CRATE="" VERSION="" SHA="" DROPS=() IGNORES=() DIFFS=()
  local file=$HERE/$1.series n=0 line words where d l listed
  [[ -f $file ]] || die "no series file patches/$1.series (forks: patches/*.series)"
  while IFS= read -r line || [[ -n $line ]]; do
    n=$((n + 1))
    line=${line%%#*}
    read -r -a words <<< "$line" || true
    ((${#words[@]})) || continue
    where="patches/$1.series:$n"
    case ${words[0]} in
      crate) ((${#words[@]} == 3)) || die "$where: expected 'crate NAME VERSION'"
        CRATE=${words[1]} VERSION=${words[2]} ;;
      sha256) [[ ${#words[@]} == 2 && ${words[1]} =~ ^[0-9a-f]{64}$ ]] \
          || die "$where: expected 'sha256' and 64 lowercase hex digits"
        SHA=${words[1]} ;;
      drop | ignore) ((${#words[@]} == 2)) || die "$where: expected '${words[0]} PATH'"
        [[ ${words[1]} != /* && /${words[1]}/ != */../* ]] || die "$where: ${words[1]}: not inside the crate"
        if [[ ${words[0]} == drop ]]; then DROPS+=("${words[1]}"); else IGNORES+=("${words[1]}"); fi ;;
      *.diff) ((${#words[@]} == 1)) && [[ ${words[0]} != */* ]] || die "$where: expected a diff's file name"
        [[ -f $HERE/${words[0]} ]] || die "$where: patches/${words[0]} does not exist"
        DIFFS+=("${words[0]}") ;;
      *) die "$where: cannot read '${line}'" ;;
    esac
  done < "$file"
  [[ -n $CRATE && -n $SHA ]] || die "patches/$1.series: needs a 'crate NAME VERSION' and a 'sha256 HEX' line"
  # (Not under --diff, whose output may be going to a new patches/NAME-*.diff.)
  [[ $mode == diff ]] && return
  for d in "$HERE/$1"-*.diff; do
    [[ -f $d ]] || continue
    d=${d##*/}
    listed=""
    for l in "${DIFFS[@]}"; do [[ $l == "$d" ]] && listed=1; done
    [[ -n $listed ]] || die "patches/$d is not in patches/$1.series: append it there (in the order it applies)"
  done
}

# Sets CRATE_FILE to the pristine crate, checked against SHA, downloading it if needed.
fetch_crate() {
  local file=$CRATE-$VERSION.crate c sum url part
  for c in "$CARGO_CACHE"/*/"$file" "$CACHE/$file"; do
    [[ -f $c ]] || continue
    sum=$(sha256_of "$c")
    if [[ $sum == "$SHA" ]]; then CRATE_FILE=$c; return; fi
    printf 'rebuild.sh: %s has sha256 %s, not %s: not using it\n' "$c" "$sum" "$SHA" >&2
  done
  url=https://static.crates.io/crates/$CRATE/$file
  mkdir -p "$CACHE"
  part=$CACHE/$file.part.$$
  curl -sSfL --retry 3 -o "$part" "$url" || { rm -f "$part"; die "cannot download $url"; }
  sum=$(sha256_of "$part")
  if [[ $sum != "$SHA" ]]; then
    rm -f "$part"
    die "$url has sha256 $sum, but patches/$NAME.series records $SHA"
  fi
  mv -f "$part" "$CACHE/$file"
  CRATE_FILE=$CACHE/$file
}

# Applies DIFFS in order inside directory $1; stops at the first that does not apply cleanly.
apply_series() {
  local d out
  for d in "${DIFFS[@]}"; do
    if ! out=$(patch -d "$1" -p1 --no-backup-if-mismatch --forward --batch --fuzz=0 \
        --reject-file=- -i "$HERE/$d" 2>&1); then
      printf '%s\n' "$out" | while IFS= read -r line; do printf '    %s\n' "$line"; done >&2
      printf 'rebuild.sh: %s %s: patches/%s does not apply to the crate + the diffs before it in patches/%s.series; stopped there\n' \
        "$CRATE" "$VERSION" "$d" "$NAME" >&2
      return 1
    fi
  done
}

# Unpacks the pristine crate into $1/built, drops DROPS and applies the series.
build() {
  local p
  mkdir -p "$1/unpack"
  tar -xzf "$CRATE_FILE" -C "$1/unpack" || die "cannot unpack $CRATE_FILE"
  [[ -d $1/unpack/$CRATE-$VERSION ]] || die "$CRATE_FILE does not unpack to $CRATE-$VERSION/"
  mv "$1/unpack/$CRATE-$VERSION" "$1/built"
  for p in "${DROPS[@]}"; do
    [[ -e $1/built/$p || -L $1/built/$p ]] \
      || die "patches/$NAME.series: drop $p: $CRATE $VERSION has no such path"
    rm -rf -- "${1:?}/built/$p"
  done
  apply_series "$1/built" || exit 1
}

# Copies patches/NAME/ without its IGNORES to $1/vendored.
copy_vendored() {
  local i
  [[ -d $HERE/$NAME ]] || die "patches/$NAME/ does not exist (--write creates it)"
  cp -R "$HERE/$NAME" "$1/vendored"
  for i in "${IGNORES[@]}"; do rm -rf -- "${1:?}/vendored/$i"; done
}

# Compares $1/built with $1/vendored; prints each differing file (as patches/NAME/PATH).
compare() {
  local a=$1/built b=$1/vendored out rc=0 line rel dir
  out=$(diff -rq "$a" "$b" 2>&1) || rc=$?
  ((rc == 0)) && return 0
  ((rc == 1)) || die "diff failed: $out"
  while IFS= read -r line; do
    if [[ $line == "Files $a/"*" differ" ]]; then
      rel=${line#"Files $a/"}
      rel=${rel%%" and $b/"*}
      printf '  patches/%s/%s: differs\n' "$NAME" "$rel"
    elif [[ $line == "Only in $b"* ]]; then
      dir=${line#"Only in $b"}
      dir=${dir%%": "*}
      printf '  patches/%s%s/%s: not in pristine + series\n' "$NAME" "$dir" "${line#*": "}"
    elif [[ $line == "Only in $a"* ]]; then
      dir=${line#"Only in $a"}
      dir=${dir%%": "*}
      printf '  patches/%s%s/%s: missing (pristine + series has it)\n' "$NAME" "$dir" "${line#*": "}"
    else
      line=${line//"$a"/"pristine+series"}
      printf '  %s\n' "${line//"$b"/"patches/$NAME"}"
    fi
  done <<< "$out"
  return 1
}

# Prints the difference built -> vendored as a diff in the series' format.
print_diff() {
  local line hdr=0 rc=0
  mv "$1/built" "$1/a"
  mv "$1/vendored" "$1/b"
  (cd "$1" && TZ=UTC0 LC_ALL=C diff -ruN a b) > "$1/out.diff" || rc=$?
  ((rc <= 1)) || die "diff failed"
  while IFS= read -r line; do
    if [[ $line == "diff -ruN a/"* ]]; then hdr=2; continue; fi
    if ((hdr > 0)) && [[ $line == "--- a/"* || $line == "+++ b/"* ]]; then
      hdr=$((hdr - 1))
      if [[ $line == "+++ "* && ${line#*$'\t'} == "1970-01-01 00:00:00"* ]]; then
        line="+++ /dev/null"  # the file goes
      fi
      line=${line%%$'\t'*}
    elif [[ $line == "Binary files "* ]]; then
      printf 'rebuild.sh: %s: a binary change cannot go in a diff\n' "$line" >&2
      continue
    fi
    printf '%s\n' "$line"
  done < "$1/out.diff"
}

# Replaces patches/NAME/ (all but its IGNORES) with $1/built.
write_fork() {
  local e i keep
  mkdir -p "$HERE/$NAME"
  shopt -s dotglob nullglob
  for e in "$HERE/$NAME"/*; do
    keep=""
    for i in "${IGNORES[@]}"; do [[ ${e##*/} == "$i" ]] && keep=1; done
    [[ -n $keep ]] || rm -rf -- "$e"
  done
  shopt -u dotglob nullglob
  cp -R "$1/built/." "$HERE/$NAME/"
}

self_test() {
  local w=$1 out first f c
  copy_vendored "$w"
  compare "$w" > "$w/out" || die "self-test: patches/$NAME/ is not pristine + series; run the check first"
  # A changed byte in a copy of the vendored tree must be named.
  f=src/lib.rs
  [[ -f $w/vendored/$f ]] || f=Cargo.toml
  IFS= read -r -n 1 c < "$w/vendored/$f" || true
  if [[ $c == x ]]; then c=y; else c=x; fi
  printf '%s' "$c" | dd of="$w/vendored/$f" bs=1 count=1 conv=notrunc status=none
  : > "$w/vendored/src/stray.rs"
  if compare "$w" > "$w/out"; then die "self-test: a changed byte in $f was not caught"; fi
  out=$(< "$w/out")
  [[ $out == *"patches/$NAME/$f: differs"* ]] || die "self-test: the changed $f was not named: $out"
  [[ $out == *"patches/$NAME/src/stray.rs: not in pristine + series"* ]] \
    || die "self-test: the stray src/stray.rs was not named: $out"
  # The series applied a second time must stop at its first diff, naming it.
  first=${DIFFS[0]}
  if out=$(apply_series "$w/built" 2>&1); then die "self-test: a diff applied twice was not refused"; fi
  [[ $out == *"patches/$first does not apply"* ]] || die "self-test: the failing diff was not named: $out"
  printf '%s %s: self-test passed: a changed byte (patches/%s/%s), a stray file and a diff that does not apply (%s) are caught\n' \
    "$CRATE" "$VERSION" "$NAME" "$f" "$first"
}

status=0
for fork in "${forks[@]}"; do
  read_series "$fork"
  fetch_crate
  work=$TMP/$NAME
  mkdir -p "$work"
  build "$work"
  case $mode in
    check)
      copy_vendored "$work"
      if compare "$work" > "$work/report"; then
        printf '%s %s: %d diffs applied, identical to patches/%s\n' "$CRATE" "$VERSION" "${#DIFFS[@]}" "$NAME"
      else
        printf '%s %s: %d diffs applied, but patches/%s differs from pristine + series:\n' \
          "$CRATE" "$VERSION" "${#DIFFS[@]}" "$NAME"
        cat "$work/report"
        printf '  (see the difference as a diff: bash patches/rebuild.sh --diff --fork %s)\n' "$NAME"
        status=1
      fi ;;
    write)
      if [[ -d $HERE/$NAME ]] && copy_vendored "$work" && compare "$work" > /dev/null; then
        printf '%s %s: %d diffs applied, identical to patches/%s (left as it was)\n' "$CRATE" "$VERSION" "${#DIFFS[@]}" "$NAME"
      else
        write_fork "$work"
        printf '%s %s: %d diffs applied, patches/%s rewritten\n' "$CRATE" "$VERSION" "${#DIFFS[@]}" "$NAME"
      fi ;;
    diff)
      copy_vendored "$work"
      print_diff "$work" ;;
    self-test)
      self_test "$work" ;;
  esac
done
exit "$status"
