;; runaway: says so, then loops forever in init_prog. The kernel stops it when its fuel (50 ms
;; of modelled CPU time) is spent: alert_user_program_stopped and a THREAD line with the
;; reason; the lower loop ends and the board goes on.
(module
  (import "kernel" "affiche" (func $affiche (param i32 i32 i32)))
  (memory (export "memory") 1)
  (data (i32.const 0) "runaway: looping")
  (func (export "init_prog") (result i32)
    (call $affiche (i32.const 16) (i32.const 8) (i32.const 0))
    (loop $forever (br $forever))
    (i32.const 0x8000)))
