# Bash completion for skelflow: commands, each command's options, module names (from
# `skelflow modules --names`), node names after --set/--target and node.port after render's --node
# (from the pipeline on the line) and .yaml files. Installed as share/bash-completion/completions/skelflow; or: source this file.
_skelflow() {
  local cur prev cmd
  cur="${COMP_WORDS[COMP_CWORD]}"
  prev="${COMP_WORDS[COMP_CWORD-1]}"
  cmd="${COMP_WORDS[1]}"
  local prog="${COMP_WORDS[0]}"
  if [[ $COMP_CWORD -eq 1 ]]; then
    COMPREPLY=($(compgen -W "run validate render modules info help --help --version" -- "$cur"))
    return
  fi
  case "$prev" in
    --output-dir|--scratch) COMPREPLY=($(compgen -d -- "$cur")); return ;;
    --memory-budget) COMPREPLY=($(compgen -W "256MiB 512MiB 1GiB 2GiB 4GiB 8GiB" -- "$cur")); return ;;
    --report) COMPREPLY=($(compgen -f -- "$cur")); return ;;
    --threads) COMPREPLY=($(compgen -W "0 1 2 4 8 16" -- "$cur")); return ;;
    -o|--output) COMPREPLY=($(compgen -f -X '!*.png' -- "$cur") $(compgen -d -- "$cur")); return ;;
    --size) COMPREPLY=($(compgen -W "640x480 1280x800 1920x1080 2048x2048" -- "$cur")); return ;;
    --camera) COMPREPLY=($(compgen -W "iso x y z" -- "$cur")); return ;;
    --volume-mode) COMPREPLY=($(compgen -W "slices mip iso volume voxels" -- "$cur")); return ;;
    --color-by) return ;;
    --set|--target|--node)
      # node ids from the pipeline named on the line: lines "  id:" under "nodes:"
      local w pipeline=""
      for w in "${COMP_WORDS[@]:2}"; do [[ $w == *.yaml || $w == *.yml ]] && pipeline="$w"; done
      if [[ -f $pipeline ]]; then
        local nodes
        nodes=$(sed -n '/^nodes:/,/^[^ ]/s/^  \([A-Za-z0-9_-]*\):.*/\1/p' "$pipeline")
        if [[ $prev == --set || $prev == --node ]]; then
          COMPREPLY=($(compgen -S . -W "$nodes" -- "$cur")); compopt -o nospace 2>/dev/null
        else
          COMPREPLY=($(compgen -W "$nodes" -- "$cur"))
        fi
      fi
      return ;;
  esac
  case "$cmd" in
    run)
      if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W "--set --threads --output-dir --allow-outside-output-dir --report --target --quiet --memory-budget --scratch --resume --help" -- "$cur"))
      else
        COMPREPLY=($(compgen -f -X '!*.@(yaml|yml)' -- "$cur") $(compgen -d -- "$cur"))
      fi ;;
    render)
      if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W "--node --output --size --color-by --camera --volume-mode --set --threads --quiet --help" -- "$cur"))
      else
        COMPREPLY=($(compgen -f -X '!*.@(yaml|yml)' -- "$cur") $(compgen -d -- "$cur"))
      fi ;;
    validate)
      if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W "--output-dir --allow-outside-output-dir --help" -- "$cur"))
      else
        COMPREPLY=($(compgen -f -X '!*.@(yaml|yml)' -- "$cur") $(compgen -d -- "$cur"))
      fi ;;
    modules)
      if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W "--markdown --names --help" -- "$cur"))
      else
        COMPREPLY=($(compgen -W "$("$prog" modules --names 2>/dev/null)" -- "$cur"))
      fi ;;
    info) COMPREPLY=($(compgen -f -- "$cur")) ;;
    help) COMPREPLY=($(compgen -W "run validate render modules info" -- "$cur")) ;;
  esac
}
shopt -s extglob 2>/dev/null
complete -F _skelflow skelflow
