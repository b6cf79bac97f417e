# Joins the firmware's region labels (`@label NAME`, in order, on the semihosting output)
# with the plugin's counts (`count N`, in the same order) and prints the tick-cost table
# and the instruction profile of the full control tick.
#
#   awk -f report.awk -v cpi=1.3 -v mhz=168 -v rate=1000 COUNTS_FILE FIRMWARE_OUTPUT
function pct(n) { return 100.0 * n * cpi * rate / (mhz * 1e6) }
BEGIN { npair = 0; nc = 0; nf = 0; nl = 0; no = 0; ni = 0; if (top == "") top = 25 }
FNR == NR {
    if ($1 == "count") counts[nc++] = $2
    else if ($1 == "call") { k = npair++; pair_n[k] = $2 + 0; $1 = ""; $2 = ""; sub(/^ +/, ""); pair_name[k] = $0 }
    else if ($1 == "incl") { k = ninc++; inc_n[k] = $2 + 0; $1 = ""; $2 = ""; sub(/^ +/, ""); inc_name[k] = $0 }
    else if ($1 == "func") { k = nf++; fn_n[k] = $2 + 0; $1 = ""; $2 = ""; sub(/^ +/, ""); fn_name[k] = $0 }
    next
}
/^@label / {
    label = substr($0, 8)
    if (nl >= nc) { missing++; nl++; next }
    n = counts[nl++]
    if (!(label in calls)) { order[no++] = label; min[label] = n; max[label] = n }
    calls[label]++; sum[label] += n
    # The period: a tick and the evaluation phase that follows it (raw counts).
    if (label ~ /^Controller::tick/) last_tick = n
    if (label ~ /^after the outputs/ && last_tick + n > period_max) period_max = last_tick + n
    if (n < min[label]) min[label] = n
    if (n > max[label]) max[label] = n
    next
}
/^@profiled / { profiled = $2 + 0; next }
/^@info / { info[ni++] = substr($0, 7); next }
END {
    if (nc == 0 || missing > 0 || nl != nc) {
        printf "tick-cost: %d labels but %d counts: the plugin did not count every region\n", nl, nc > "/dev/stderr"
        exit 1
    }
    overhead = min["overhead"]
    printf "\nInstructions per call on the Cortex-M4 (QEMU mps2-an386, -icount shift=0, TCG plugin;\n"
    printf "image: %s; measurement overhead of %d instructions subtracted).\n", build, overhead
    printf "%% = share of a %d MHz Cortex-M4", mhz
    printf " at %d Hz, assuming %.2f cycles per instruction (flash wait states,\n", rate, cpi
    printf "load/FPU latencies; the emulator counts instructions, not cycles).\n\n"
    printf "%-58s %6s %9s %9s %9s %7s %7s\n", "part", "calls", "min", "mean", "max", "%mean", "%max"
    line = sprintf("%0115d", 0); gsub(/0/, "-", line); print line
    for (i = 0; i < no; i++) {
        l = order[i]
        if (l == "overhead") continue
        mn = min[l] - overhead; mx = max[l] - overhead; me = sum[l] / calls[l] - overhead
        printf "%-58s %6d %9d %9.0f %9d %6.1f%% %6.1f%%\n", l, calls[l], mn, me, mx, pct(me), pct(mx)
        if (l ~ /^Controller::tick/) { tick_sum += sum[l] - calls[l] * overhead; tick_calls += calls[l]
            if (mx > tick_max) tick_max = mx }
        if (l ~ /^after the outputs/) { ev_sum += sum[l] - calls[l] * overhead; ev_calls += calls[l]
            if (mx > ev_max) ev_max = mx }
    }
    print line
    if (tick_calls > 0) {
        printf "Full tick over the scenario (readings to outputs): mean %.0f, max %d instructions%s;\n", tick_sum / tick_calls, tick_max, budget != "" ? sprintf(" (budget %d: %s)", budget, tick_max <= budget + 0 ? "met" : "NOT MET") : ""
        printf "at the max: %.1f%% of the CPU at %d Hz, %.1f%% at 5 kHz.\n", pct(tick_max), rate, pct(tick_max) * 5000 / rate
    }
    if (ev_calls > 0) {
        period = period_max - 2 * overhead
        printf "After the outputs (measured pose, checker stages, tool flanks): mean %.0f, max %d;\n", ev_sum / ev_calls, ev_max
        printf "the whole period (tick + after the outputs): mean %.0f, max %d instructions%s, %.1f%% of the CPU at %d Hz at the max.\n", (tick_sum + ev_sum) / tick_calls, period, period_budget != "" ? sprintf(" (budget %d: %s)", period_budget, period <= period_budget + 0 ? "met" : "NOT MET") : "", pct(period), rate
        if (period_budget != "" && period > period_budget + 0) {
            printf "tick-cost: the worst period (%d) exceeds PERIOD_BUDGET=%d\n", period, period_budget > "/dev/stderr"
            over = 1
        }
    } else if (tick_calls > 0 && period_budget != "") {
        printf "tick-cost: no work after the outputs was measured (PERIOD_BUDGET needs it)\n" > "/dev/stderr"
        over = 1
    }
    if (tick_calls > 0) {
        if (budget != "" && tick_max > budget + 0) {
            printf "tick-cost: the worst full tick (%d) exceeds TICK_BUDGET=%d\n", tick_max, budget > "/dev/stderr"
            over = 1
        }
    }
    for (i = 0; i < ni; i++) print "note: " info[i]
    if (nf > 0 && tick_calls > 0) {
        if (profiled > 0 && profiled != tick_calls) {
            tick_calls = profiled
            printf "\n(The profile covers %d ticks of the scenario: TICK_COST_PROFILE_TICKS.)\n", profiled
        }
        total = 0
        for (i = 0; i < nf; i++) total += fn_n[i]
        printf "\nWhere the instructions of the full tick go (per function, after inlining; %d ticks):\n", tick_calls
        printf "%12s %7s  %s\n", "per tick", "share", "function"
        for (i = 0; i < nf && i < top; i++)
            printf "%12.0f %6.1f%%  %s\n", fn_n[i] / tick_calls, 100 * fn_n[i] / total, fn_name[i]
        # Helpers (memcpy, soft-float, libm) by calling function, largest first.
        for (i = 0; i < npair; i++) idx[i] = i
        for (i = 1; i < npair; i++) { v = idx[i]; j = i - 1
            while (j >= 0 && pair_n[idx[j]] < pair_n[v]) { idx[j + 1] = idx[j]; j-- }
            idx[j + 1] = v }
        # Inclusive: a function with everything it called, largest first.
        for (i = 0; i < ninc; i++) jdx[i] = i
        for (i = 1; i < ninc; i++) { v = jdx[i]; j = i - 1
            while (j >= 0 && inc_n[jdx[j]] < inc_n[v]) { jdx[j + 1] = jdx[j]; j-- }
            jdx[j + 1] = v }
        if (ninc > 0) {
            printf "\nInclusive (a function with all it calls, per tick; shadow call stack):\n"
            for (i = 0; i < ninc && i < 2 * top; i++)
                printf "%12.0f %6.1f%%  %s\n", inc_n[jdx[i]] / tick_calls, 100 * inc_n[jdx[i]] / total, inc_name[jdx[i]]
        }
        printf "\nHelper functions by caller (memcpy, soft-float, libm; per tick):\n"
        for (i = 0; i < npair && i < top; i++)
            printf "%12.0f %6.1f%%  %s\n", pair_n[idx[i]] / tick_calls, 100 * pair_n[idx[i]] / total, pair_name[idx[i]]
    }
    if (over) exit 1
}
