#!/usr/bin/env bash
# Benchmark (prints figures; not a test): what starting one LIGGGHTS process costs under each
# launcher, inside a Slurm allocation of 1 CPU on the local cluster (deploy/slurm/local-cluster.sh
# start first). The engine runs a deck that only creates a box, so the time is launch + MPI init +
# engine start-up + exit. Usage: tests/bench/bench_slurm_launch.sh [repetitions]
set -euo pipefail
n=${1:-5}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/empty.in" <<'DECK'
region box block 0 1 0 1 0 1
create_box 1 box
DECK
cat > "$work/bench.sh" <<SCRIPT
#!/usr/bin/env bash
cd "$work"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
time_it() {  # label command...
  local label=\$1; shift
  local t0 t1
  t0=\$(date +%s.%N)
  for i in \$(seq 1 $n); do "\$@" -in empty.in -log none -screen /dev/null >/dev/null 2>&1; done
  t1=\$(date +%s.%N)
  echo "\$label \$(echo "(\$t1 - \$t0) / $n" | bc -l | cut -c1-5) s per start"
}
time_it "direct:" liggghts
time_it "mpirun -np 1:" mpirun -np 1 --bind-to none liggghts
time_it "srun --mpi=pmix -n 1 --exclusive:" srun --mpi=pmix -n 1 --exclusive liggghts
SCRIPT
chmod +x "$work/bench.sh"
sbatch --wait --quiet -n 1 -t 10 -o "$work/out.txt" "$work/bench.sh"
cat "$work/out.txt"
