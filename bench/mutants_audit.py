"""Mutants written by an audit without reading the tests (see bench/mutants.py for how they
are run): each is a small change to the source that a user would notice. The fields are those
of bench/mutants.py's Mutant: name, what it changes, path, old text (found exactly once),
new text.
"""

from __future__ import annotations

AUDIT: tuple[tuple[str, str, str, str, str], ...] = (
    # ---- the semantics core: values, new(x) and the end conditions, the Rule table of the modes
    ("audit-negative-index-reads",
     "a negative index reads from the end of the array (a[-1] is the last element) instead of "
     "failing with E802",
     "rssm_core/values.py",
     "    if 0 <= i < size:\n"
     "        return a.item(i) if floats else a[i]\n",
     "    if -size <= i < size:\n"
     "        return a.item(i) if floats else a[i]\n"),
    ("audit-negative-index-writes",
     "assigning to a[-1] replaces the last element instead of failing with E802",
     "rssm_core/values.py",
     "    if not 0 <= i < size:\n"
     '        raise _fail(where, f"index {i} is out of range',
     "    if not -size <= i < size:\n"
     '        raise _fail(where, f"index {i} is out of range'),
    ("audit-fmin-nan-right-only",
     "min(nan, 1.0) and clamp(nan, 0.0, 1.0) give 1.0: in min a NaN propagates only from its "
     "right operand",
     "rssm_core/values.py",
     '    """The smaller float; NaN when either is NaN."""\n'
     "    if x != x or y != y:\n",
     '    """The smaller float; NaN when either is NaN."""\n'
     "    if y != y:\n"),
    ("audit-range-default-low-bound",
     "a range variable declared without an initial value starts at its low bound (-5 for "
     "-5..5), not at 0",
     "rssm_core/values.py",
     "        return min(max(0, d[1]), d[2])   # 0, or the bound nearest to it\n",
     "        return d[1]                      # the low bound\n"),
    ("audit-range-upper-bound-excluded",
     "storing the upper bound into a range (3 into 0..3) fails with E802 (the range is taken "
     "half-open)",
     "rssm_core/values.py",
     "    if lo <= x <= hi:\n"
     "        return x\n"
     "    of = ",
     "    if lo <= x < hi:\n"
     "        return x\n"
     "    of = "),
    ("audit-bool-accepted-as-int",
     "an external operation or device returning True where an int is declared gets 1 instead "
     "of E803",
     "rssm_core/values.py",
     "def _to_int(v: Any) -> int:\n"
     "    if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):\n",
     "def _to_int(v: Any) -> int:\n"
     "    if not isinstance(v, int | np.integer):\n"),
    ("audit-new-only-last-input",
     "when two inputs receive fresh data in one iteration, new() holds only for the one "
     "received last",
     "rssm_core/iteration.py",
     "        self.pending |= 1 << k\n",
     "        self.pending = 1 << k\n"),
    ("audit-failing-condition-holds",
     "a terminal or error condition that fails to evaluate counts as holding (true) instead "
     "of false",
     "rssm_core/iteration.py",
     "            failed = True\n"
     "            values[name] = False\n",
     "            failed = True\n"
     "            values[name] = True\n"),
    ("audit-failing-condition-no-error",
     "a condition that fails to evaluate does not make the behaviour's error conditions hold",
     "rssm_core/iteration.py",
     "            fail(e)\n"
     "            failed = True\n",
     "            fail(e)\n"),
    ("audit-rule-bn-not-acknowledged",
     "in the Rule table a blocking producer with a non-blocking consumer gets no "
     "acknowledgement (on ROS 2 the producer then waits for ever)",
     "rssm_core/modes.py",
     "            return Rule(True, False, False, True, True)\n",
     "            return Rule(True, False, False, True, False)\n"),
    ("audit-rule-nb-consumer-does-not-wait",
     "in the Rule table the blocking consumer of a non-blocking producer does not wait for "
     "fresh data (on ROS 2 it goes on with what it had)",
     "rssm_core/modes.py",
     "            return Rule(False, True, True, False, False)\n",
     "            return Rule(False, True, False, True, False)\n"),
    # ---- the one expression compiler (interpreter, verifier conditions, ROS 2 nodes)
    ("audit-float-sum-unparenthesised",
     "float + - * are written without parentheses, so 2.0 * (a - b) computes 2.0 * a - b",
     "rssm_dsl/pycode.py",
     '            return f"({a} {op} {b})"\n'
     '        fn = "div" if op == "/" else "mod"\n',
     '            return f"{a} {op} {b}"\n'
     '        fn = "div" if op == "/" else "mod"\n'),
    ("audit-ordering-unparenthesised",
     "< <= > >= are written without parentheses, so (a < b) == (c < d) becomes a Python chain "
     "a < b == c < d",
     "rssm_dsl/pycode.py",
     '        if op in ("<", "<=", ">", ">="):\n'
     '            return f"({a} {op} {b})"\n',
     '        if op in ("<", "<=", ">", ">="):\n'
     '            return f"{a} {op} {b}"\n'),
    ("audit-equality-unparenthesised",
     "== and != of scalars are written without parentheses, so (a == b) != (c == d) becomes a "
     "Python chain",
     "rssm_dsl/pycode.py",
     '                return f"({a} {op} {b})"\n'
     '            return f"_rt.equal(',
     '                return f"{a} {op} {b}"\n'
     '            return f"_rt.equal('),
    ("audit-and-or-right-first",
     "`and`/`or` evaluate their right operand first: `i < 3 and a[i] > 0` fails (E802) when i "
     "is 3",
     "rssm_dsl/pycode.py",
     '            return f"({self.expr(e.left, BOOL)} {op} {self.expr(e.right, BOOL)})"\n',
     '            return f"({self.expr(e.right, BOOL)} {op} {self.expr(e.left, BOOL)})"\n'),
    ("audit-if-expr-unparenthesised",
     "`if c then a else b` is written without parentheses, so x + (if c then 1.0 else 0.0) "
     "gives 0.0 when c is false",
     "rssm_dsl/pycode.py",
     '                return f"({a} if {c} else {b})", t\n',
     '                return f"{a} if {c} else {b}", t\n'),
    ("audit-atan2-arguments-swapped",
     "atan2(y, x) computes atan2(x, y)",
     "rssm_dsl/pycode.py",
     '            return f"math.atan2({self.expr(e.args[0], FLOAT)}, {self.expr(e.args[1], FLOAT)})"\n',
     '            return f"math.atan2({self.expr(e.args[1], FLOAT)}, {self.expr(e.args[0], FLOAT)})"\n'),
    ("audit-narrow-range-unchecked",
     "a value of a range overlapping the target range on one side (0..10 stored into 0..3) is "
     "stored unchecked",
     "rssm_dsl/pycode.py",
     "        return not (isinstance(src, RangeT) and dst.lo <= src.lo and src.hi <= dst.hi)\n",
     "        return not (isinstance(src, RangeT) and (dst.lo <= src.lo or src.hi <= dst.hi))\n"),
    ("audit-int-not-widened",
     "an int stored where a float is expected stays an int (x: float := 1 holds 1, not 1.0)",
     "rssm_dsl/pycode.py",
     "        if is_int(src) and dst == FLOAT:\n"
     '            return f"float({code})"\n',
     "        if is_int(src) and dst == FLOAT:\n"
     "            return code\n"),
    # ---- the HPN builder: channels, arrangements, the behaviour pattern, device nets
    ("audit-channel-starts-full",
     "every channel starts full (a default value waiting to be taken) instead of empty",
     "rssm_dsl/hpn/build.py",
     '                (FusionName.FULL, p_ends.full + c_ends.full, False, "full"),\n'
     '                (FusionName.EMPTY, p_ends.empty + c_ends.empty, True, "empty"),\n',
     '                (FusionName.FULL, p_ends.full + c_ends.full, True, "full"),\n'
     '                (FusionName.EMPTY, p_ends.empty + c_ends.empty, False, "empty"),\n'),
    ("audit-device-loops-past-receive",
     "a device's loop goes back to its step, not to its receive: it receives its inputs only "
     "once",
     "rssm_dsl/hpn/build.py",
     'f"{d.id} loops", Role.ITERATION), [first])\n',
     'f"{d.id} loops", Role.ITERATION), [op])\n'),
    ("audit-iteration-through-begin",
     "a behaviour's next iteration goes back through its start transition (t_in), which waits "
     "for another tick: a paced iteration takes two periods",
     "rssm_dsl/hpn/build.py",
     "        self._arcs(pid, [last], t4, [f_page])\n",
     '        self._arcs(pid, [last], t4, [N.place(j, v, w, "in")])\n'),
    ("audit-parallel-waits-last-only",
     "a parallel arrangement `a | b` ends when its last item ends, not when all have",
     "rssm_dsl/hpn/build.py",
     "                        starts += s\n"
     "                        ends += e\n",
     "                        starts += s\n"
     "                        ends = e\n"),
    ("audit-conditions-before-receive",
     "the terminal/continue transitions take the token before the receive: an iteration may "
     "end without receiving",
     "rssm_dsl/hpn/build.py",
     "            self._arcs(pid, [p2], t3, [rcv])\n"
     "            last = rcv\n",
     "            self._arcs(pid, [p2], t3, [rcv])\n"),
    # ---- the interpreter's scheduler and clock: seeded choice, ticks, eager=False, concurrent mode
    ("audit-choice-never-last",
     "with three or more enabled transitions the seeded choice never picks the "
     "highest-numbered one",
     "rssm_dsl/interp/scheduler.py",
     "                        t = sorted(enabled)[int(rnd() * n)]\n",
     "                        t = sorted(enabled)[int(rnd() * (n - 1))]\n"),
    ("audit-scan-two-takes-first",
     "among two active transitions with conditions or ticks, the first is always taken (no "
     "seeded choice)",
     "rssm_dsl/interp/scheduler.py",
     "        t = active[int(self.rnd() * len(active))] if len(active) > 1 else active[0]\n"
     "        gate = gates[t]\n",
     "        t = active[int(self.rnd() * len(active))] if len(active) > 2 else active[0]\n"
     "        gate = gates[t]\n"),
    ("audit-next-tick-latest",
     "when nothing can fire, time moves to the latest pending tick of an enabled paced "
     "transition, not the earliest",
     "rssm_dsl/interp/scheduler.py",
     "            if gate is not None and gate.next > now and (nxt is None or gate.next < nxt):\n",
     "            if gate is not None and gate.next > now and (nxt is None or gate.next > nxt):\n"),
    ("audit-until-excludes-its-tick",
     "--until T stops before the tick at exactly T: an iteration due at t = T does not run",
     "rssm_dsl/interp/scheduler.py",
     "        if self.until is not None and nxt > self.until:\n",
     "        if self.until is not None and nxt >= self.until:\n"),
    ("audit-eager-false-ignored",
     "SimOptions(eager=False) still fires local steps at once once the run has started (only "
     "the first ones take part in the choice)",
     "rssm_dsl/interp/scheduler.py",
     "            eager = self.eager if options.eager and options.forced is None else bytearray(\n",
     "            eager = self.eager if options.forced is None else bytearray(\n"),
    ("audit-concurrent-tick-not-started",
     "in concurrent mode firing a paced transition does not move its subsystem's next tick: "
     "the rate is not honoured",
     "rssm_dsl/interp/scheduler.py",
     "        gate = rt.gates[t]\n"
     "        if gate is not None:\n"
     "            gate.start(now)\n"
     "        game.consume(t)\n",
     "        gate = rt.gates[t]\n"
     "        game.consume(t)\n"),
    ("audit-concurrent-wait-ms",
     "in concurrent mode the wait for the next tick is computed in milliseconds instead of "
     "seconds (it waits a thousand times too long unless an operation finishes)",
     "rssm_dsl/interp/scheduler.py",
     "        timeout = None if nxt is None else max(0.0, (nxt - now) / 1e9)\n",
     "        timeout = None if nxt is None else max(0.0, (nxt - now) / 1e6)\n"),
    ("audit-overrun-any-late-start",
     "an iteration that starts any time after its tick counts as an overrun, not only one "
     "that starts a whole period late",
     "rssm_dsl/interp/clock.py",
     "            if now >= self.next + period:\n"
     "                self.overruns += 1\n",
     "            if now > self.next:\n"
     "                self.overruns += 1\n"),
    ("audit-first-tick-one-period",
     "a paced subsystem's (or device's) first iteration starts one period after time 0 "
     "instead of at 0",
     "rssm_dsl/interp/clock.py",
     "        self.next = 0          # the first iteration starts at time 0\n",
     "        self.next = self.period  # the first iteration starts after one period\n"),
    # ---- the verifier's reductions: stubborn-set conditions, visibility, cycle proviso
    ("audit-stubborn-disable-readers",
     "firing a transition that only reads a place (a tracked value) drops the other readers "
     "of that place from the enabled set: reachable states are missed",
     "rssm_dsl/verify/stubborn.py",
     "            for p in bits(nb.consume[t]):\n"
     "                self.disable[t] |= nb.consumers[p]\n",
     "            for p in bits(nb.pre[t]):\n"
     "                self.disable[t] |= nb.consumers[p]\n"),
    ("audit-stubborn-read-place-unprotected",
     "the conflicts of an enabled transition omit those that empty a place it only reads (a "
     "value it tests can change under it: D1/D2 broken for test arcs)",
     "rssm_dsl/verify/stubborn.py",
     "            for p in bits(nb.pre[t]):\n"
     "                self.dependent[t] |= self.leave[p]\n",
     "            for p in bits(nb.consume[t]):\n"
     "                self.dependent[t] |= self.leave[p]\n"),
    ("audit-stubborn-visible-enabled-only",
     "V weakened: an enabled visible transition brings only the enabled visible ones, not the "
     "disabled ones that may be enabled from outside the set",
     "rssm_dsl/verify/stubborn.py",
     "                    add |= self.visible\n",
     "                    add |= self.visible & en\n"),
    ("audit-stubborn-lonely-despite-up-set",
     "a transition in conflict with nothing is taken alone even when the up-set (for "
     "safeness) is not empty",
     "rssm_dsl/verify/stubborn.py",
     "        if not up:\n"
     "            lonely = en & self.lonely\n",
     "        if True:\n"
     "            lonely = en & self.lonely\n"),
    ("audit-proviso-expands-nothing",
     "the cycle proviso marks a marking on a cycle as fully expanded but fires again only "
     "what it had fired: a transition may still be ignored for ever around the cycle",
     "rssm_dsl/verify/stubborn.py",
     "            rest = st.enabled_of[v] & ~st.fired_of[v]\n",
     "            rest = st.fired_of[v]\n"),
    ("audit-proviso-one-round",
     "after the cycle proviso expands markings fully the search ends without exploring what "
     "those expansions found",
     "rssm_dsl/verify/stubborn.py",
     "        return bool(breakers)\n",
     "        return False\n"),
    ("audit-visible-value-one-mask",
     "a transition moving a tracked value from one value to another is invisible (all the "
     "value's places taken as one), so property atoms over values may be reordered away",
     "rssm_dsl/verify/userprops.py",
     "            masks += [1 << p.index for p in net.places if p.channel == key]\n",
     "            masks.append(sum(1 << p.index for p in net.places if p.channel == key))\n"),
    ("audit-visible-behaviour-whole-subsystem",
     "a behaviour switch is invisible for `SUB in BEH` (the atom's places are taken as every "
     "place of the subsystem)",
     "rssm_dsl/verify/userprops.py",
     "                             if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour))\n",
     "                             if p.subsystem == a.subsystem_id))\n"),
    # ---- the ROS 2 runtime: acknowledgements, fresh samples, ticks (ros2-marked tests only)
    ("audit-ros2-send-waits-for-previous",
     "a blocking producer's send waits only for the acknowledgement of its previous sample, "
     "not this one",
     "rssm_dsl/ros2/runtime/channels.py",
     "        while self.acked < self.seq:\n",
     "        while self.acked < self.seq - 1:\n"),
    ("audit-ros2-stale-sample-new",
     "the sample last taken counts as fresh again: a blocking receive takes a stale sample "
     "and new(x) holds",
     "rssm_dsl/ros2/runtime/channels.py",
     "        return bool(epoch != self.taken_epoch or seq > self.taken_seq)\n",
     "        return bool(epoch != self.taken_epoch or seq >= self.taken_seq)\n"),
    ("audit-ros2-ack-on-arrival",
     "the consumer acknowledges a sample when it arrives, not when its receive takes it: a "
     "blocking producer ends its send before the consumer took the data",
     "rssm_dsl/ros2/runtime/channels.py",
     "                self.latest = Sample(info.epoch, info.seq, msg)\n",
     "                self.latest = Sample(info.epoch, info.seq, msg)\n"
     "                if self.ack_pub is not None:\n"
     "                    self.ack_pub.publish(self.spec.ack(epoch=info.epoch, seq=info.seq))\n"),
    ("audit-ros2-overwritten-off-by-one",
     "the consumer counts the sample it takes as overwritten too (overwritten counts every "
     "sample since the last taken)",
     "rssm_dsl/ros2/runtime/channels.py",
     "            self.overwritten += sample.seq - self.taken_seq - 1\n",
     "            self.overwritten += sample.seq - self.taken_seq\n"),
    ("audit-ros2-producer-mode-from-consumer",
     "a producer waits for the acknowledgement when the consumer is blocking (the wrong "
     "side's mode), not when it is",
     "rssm_dsl/ros2/runtime/channels.py",
     "        self.blocking = spec.rule.producer_waits_until_taken\n",
     "        self.blocking = spec.rule.consumer_waits_for_data\n"),
    ("audit-ros2-failure-sticks",
     "on ROS 2 an operation failure is not forgotten after its iteration: every later "
     "iteration's error conditions hold",
     "rssm_dsl/ros2/runtime/subsystem.py",
     "            self.failed = None\n"
     "            self._iteration_done(beh)\n",
     "            self._iteration_done(beh)\n"),
    ("audit-ros2-new-without-data",
     "on ROS 2 a non-blocking receive that finds nothing fresh still sets new(x)",
     "rssm_dsl/ros2/runtime/subsystem.py",
     "        taken, value = yield from self.take(buffer)\n"
     "        if not taken:\n"
     "            return\n"
     '        setattr(self.state, "v_" + buffer, value)\n'
     "        self.new.received(self.input_names.index(buffer))\n",
     "        taken, value = yield from self.take(buffer)\n"
     "        self.new.received(self.input_names.index(buffer))\n"
     "        if not taken:\n"
     "            return\n"
     '        setattr(self.state, "v_" + buffer, value)\n'),
    ("audit-ros2-overrun-one-period",
     "on ROS 2 an iteration that starts one period after the previous one (on time) already "
     "counts as an overrun in the diagnostics, not only one two periods or more later",
     "rssm_dsl/ros2/runtime/loop.py",
     "            if now - last >= 2 * self.period:\n",
     "            if now - last >= self.period:\n"),
    ("audit-ros2-tick-not-consumed",
     "on ROS 2 a node's timer tick is never consumed: after the first period the iterations "
     "run unpaced",
     "rssm_dsl/ros2/runtime/loop.py",
     "        self.ticked = 0\n"
     "        self.last_start = now\n",
     "        self.last_start = now\n"),
    ("audit-ros2-nonblocking-no-drain",
     "on ROS 2 a non-blocking receive does not first take in the samples that arrived: it "
     "finds nothing new though a sample is waiting",
     "rssm_dsl/ros2/runtime/loop.py",
     "            self.drain()\n"
     "            if not box.fresh():\n",
     "            if not box.fresh():\n"),
)
