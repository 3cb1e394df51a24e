# ctest -R MixedSweep.CountsTheSettingsMeetingEachBar: runs pcdp_mixed_sweep on a few settings
# with --json and checks that its per-bar counts ("settings_meeting") are those of its own rows:
# recall >= 0.90, valid rejected <= 1 %, no phantom cell, and all three; and that its counts of
# what check_consistency removes after the filters, and of the kept mixed pixels standing more
# than 0.3 m above the true top by what surrounds them and next to a nod turn, add up; and so do
# its counts of cells more than 0.3 m below the true top and against a perfect filter's map.
# Usage: cmake -DSWEEP=<pcdp_mixed_sweep> -DOUT=<json file> -P check_settings_meeting.cmake
execute_process(COMMAND "${SWEEP}" --index 0 --index 3 --index 19 --index 21 --misses 0 --json "${OUT}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "pcdp_mixed_sweep exited ${rc}")
endif()
file(READ "${OUT}" json)
function(to_ten_thousandths value out)
  # string(JSON) gives the number back as a double prints (0.8760 -> 0.876, 0.1029 ->
  # 0.10290000000000001): round it to the 4 decimals the sweep wrote.
  if(NOT value MATCHES "^([0-9]+)(\\.([0-9]*))?$")
    message(FATAL_ERROR "not a plain non-negative number: ${value}")
  endif()
  set(whole "${CMAKE_MATCH_1}")
  set(frac "${CMAKE_MATCH_3}00000")
  string(SUBSTRING "${frac}" 0 5 frac)
  string(REGEX REPLACE "^0+([0-9])" "\\1" frac "${frac}")
  math(EXPR v "(${whole} * 100000 + ${frac} + 5) / 10")
  set(${out} ${v} PARENT_SCOPE)
endfunction()
# read_row(K VAR=FIELD...): sets each VAR to FIELD of row K of the sweep's settings.
function(read_row k)
  foreach(pair ${ARGN})
    string(REPLACE "=" ";" var_field "${pair}")
    list(GET var_field 0 var)
    list(GET var_field 1 field)
    string(JSON value GET "${json}" settings ${k} ${field})
    set(${var} "${value}" PARENT_SCOPE)
  endforeach()
endfunction()
string(JSON n LENGTH "${json}" settings)
set(recall 0)
set(valid 0)
set(phantom 0)
set(all 0)
math(EXPR last "${n} - 1")
set(cc_valid 0)
set(cc_mixed 0)
set(turn_mixed 0)
set(turn_last 0)
set(turn_all 0)
set(rows_phantom_mixed 0)
set(below 0)
set(below_unseen 0)
set(lowered 0)
set(emptied 0)
foreach(k RANGE ${last})
  # The map's other side: the cells more than 0.3 m below the lowest true top a perfect filter's
  # map shares are among them; the cells the false rejections lower or empty are among the
  # perfect map's cells, and lowered and emptied are disjoint.
  read_row(${k} cb=cells_below_true_top cu=cells_below_true_top_unseen cp=perfect_filter_cells
           cl=cells_lowered_by_false_rejections ce=cells_emptied_by_false_rejections)
  math(EXPR cle "${cl} + ${ce}")
  if(cu GREATER cb OR cle GREATER cp)
    message(FATAL_ERROR "row ${k}: ${cb} cells below the true top (${cu} also with a perfect filter); ${cl} lowered and "
                        "${ce} emptied of the perfect map's ${cp}")
  endif()
  math(EXPR below "${below} + ${cb}")
  math(EXPR below_unseen "${below_unseen} + ${cu}")
  math(EXPR lowered "${lowered} + ${cl}")
  math(EXPR emptied "${emptied} + ${ce}")
  # The kept mixed pixels more than 0.3 m above the true top, those among them on a line next to a
  # nod turn and those on the last line before one: each at most the one before (upper bounds;
  # the sums below must also fall strictly between 0 and the whole).
  read_row(${k} pm=phantom_mixed_pixels pt=phantom_mixed_pixels_next_to_nod_turn
           pl=phantom_mixed_pixels_on_last_line_before_nod_turn mt=mixed_next_to_nod_turn n_mixed=mixed)
  if(pt GREATER pm OR pl GREATER pt OR pt GREATER mt OR mt GREATER n_mixed)
    message(FATAL_ERROR "row ${k}: ${pt} kept mixed pixels above the true top next to a nod turn (${pl} on the "
                        "last line before), of ${pm}; ${mt} of all ${n_mixed} mixed pixels next to one")
  endif()
  math(EXPR turn_mixed "${turn_mixed} + ${pt}")
  math(EXPR turn_last "${turn_last} + ${pl}")
  math(EXPR turn_all "${turn_all} + ${mt}")
  math(EXPR rows_phantom_mixed "${rows_phantom_mixed} + ${pm}")
  # What check_consistency removes after the filters: among the returns the filters kept.
  read_row(${k} cv=check_consistency_valid cm=check_consistency_mixed n_valid=valid n_valid_rejected=valid_rejected
           n_mixed_rejected=mixed_rejected)
  math(EXPR kept_valid "${n_valid} - ${n_valid_rejected}")
  math(EXPR kept_mixed "${n_mixed} - ${n_mixed_rejected}")
  if(cv GREATER kept_valid OR cm GREATER kept_mixed)
    message(FATAL_ERROR "row ${k}: check_consistency removes ${cv} valid of ${kept_valid} kept, ${cm} mixed of ${kept_mixed} kept")
  endif()
  math(EXPR cc_valid "${cc_valid} + ${cv}")
  math(EXPR cc_mixed "${cc_mixed} + ${cm}")
  read_row(${k} r=mixed_recall v=valid_rejected_pct p=phantom_cells)
  # CMake compares integers only: the 4-decimal fields in units of 0.0001.
  to_ten_thousandths("${r}" r_int)
  to_ten_thousandths("${v}" v_int)
  set(ok_r 0)
  set(ok_v 0)
  set(ok_p 0)
  if(r_int GREATER_EQUAL 9000)
    set(ok_r 1)
  endif()
  if(v_int LESS_EQUAL 10000)
    set(ok_v 1)
  endif()
  if(p EQUAL 0)
    set(ok_p 1)
  endif()
  math(EXPR recall "${recall} + ${ok_r}")
  math(EXPR valid "${valid} + ${ok_v}")
  math(EXPR phantom "${phantom} + ${ok_p}")
  if(ok_r AND ok_v AND ok_p)
    math(EXPR all "${all} + 1")
  endif()
endforeach()
foreach(key recall_at_least_0_90 valid_rejected_at_most_1_pct no_phantom_cell all_three settings)
  string(JSON got_${key} GET "${json}" settings_meeting ${key})
endforeach()
set(want "${recall} ${valid} ${phantom} ${all} ${n}")
set(got "${got_recall_at_least_0_90} ${got_valid_rejected_at_most_1_pct} ${got_no_phantom_cell} ${got_all_three} ${got_settings}")
if(NOT want STREQUAL got)
  message(FATAL_ERROR "settings_meeting says ${got}; its rows say ${want} (recall, valid, phantom, all, of)")
endif()
string(FIND "${out}" "settings meeting each bar: recall >= 0.90 ${recall} / ${n}; valid rejected <= 1 % ${valid} / ${n}; no phantom cell ${phantom} / ${n}; all three ${all} / ${n}" at)
if(at LESS 0)
  message(FATAL_ERROR "the printed summary does not say ${want}:\n${out}")
endif()
# Each count must lie strictly between 0 and the number of settings, or a wrong count for that
# bar could pass unseen.
foreach(count ${recall} ${valid} ${phantom} ${all})
  if(count EQUAL 0 OR count EQUAL n)
    message(FATAL_ERROR "the chosen settings no longer mix met and missed bars (${want}): choose others")
  endif()
endforeach()
# What check_consistency removes after the filters ("check_consistency_valid", "_mixed", each
# row bounded in the loop above): the pooled row sums the rows, the printed line says the pooled
# numbers, and the chosen settings have some (or the check is empty).
string(JSON pooled_cv GET "${json}" pooled check_consistency_valid)
string(JSON pooled_cm GET "${json}" pooled check_consistency_mixed)
if(NOT "${pooled_cv} ${pooled_cm}" STREQUAL "${cc_valid} ${cc_mixed}" OR cc_valid EQUAL 0 OR cc_mixed EQUAL 0)
  message(FATAL_ERROR "check_consistency: pooled ${pooled_cv} valid, ${pooled_cm} mixed; rows sum to ${cc_valid}, ${cc_mixed}")
endif()
string(FIND "${out}" "(column +cc): ${cc_mixed} more mixed pixels, ${cc_valid} more valid returns" at)
if(at LESS 0)
  message(FATAL_ERROR "the printed line does not say ${cc_mixed} mixed pixels and ${cc_valid} valid returns:\n${out}")
endif()
# The kept mixed pixels standing more than 0.3 m above the true top, sorted by what surrounds
# them: there are some, in more than one kind, and the printed rows add up to the count by truth
# label (both are counted in one place: this checks the printing and the sorting's coverage).
if(NOT out MATCHES "by truth label:[^\n]* mixed_pixel ([0-9]+);")
  message(FATAL_ERROR "no kept mixed pixel more than 0.3 m above the true top on these settings:\n${out}")
endif()
set(phantom_mixed ${CMAKE_MATCH_1})
string(REGEX MATCH "by what surrounds them:\n(    [^\n]*\n)+" kinds "${out}")
string(REGEX MATCHALL "    [a-z][^\n]* ([0-9]+)\n" rows "${kinds}")
set(sum 0)
foreach(row ${rows})
  string(REGEX MATCH "([0-9]+)\n$" _ "${row}")
  math(EXPR sum "${sum} + ${CMAKE_MATCH_1}")
endforeach()
list(LENGTH rows kinds_count)
if(NOT sum EQUAL phantom_mixed OR kinds_count LESS 2)
  message(FATAL_ERROR "the ${kinds_count} rows by what surrounds them add up to ${sum}, not ${phantom_mixed}:\n${kinds}")
endif()
# Those next to a nod turn: the pooled row sums the rows and agrees with the count by truth
# label, the printed line says the pooled number, and it lies strictly between 0 and all of them
# (or a wrong count could pass unseen).
string(JSON pooled_pm GET "${json}" pooled phantom_mixed_pixels)
string(JSON pooled_pt GET "${json}" pooled phantom_mixed_pixels_next_to_nod_turn)
string(JSON pooled_pl GET "${json}" pooled phantom_mixed_pixels_on_last_line_before_nod_turn)
string(JSON pooled_mt GET "${json}" pooled mixed_next_to_nod_turn)
if(NOT "${pooled_pm} ${pooled_pt} ${pooled_pl} ${pooled_mt}" STREQUAL "${phantom_mixed} ${turn_mixed} ${turn_last} ${turn_all}"
   OR NOT rows_phantom_mixed EQUAL phantom_mixed)
  message(FATAL_ERROR "kept mixed pixels above the true top: pooled ${pooled_pm}, ${pooled_pt} next to a nod turn, "
                      "${pooled_pl} on the last line before, ${pooled_mt} of all mixed pixels next to one; rows sum to "
                      "${rows_phantom_mixed}, ${turn_mixed}, ${turn_last}, ${turn_all}; printed ${phantom_mixed}")
endif()
# Both kinds of line hold some (the last before the reversal and the first after), so that a
# rule that missed either would change a count that is checked.
if(NOT out MATCHES "  of them on a line next to a nod turn [^\n]*: ${turn_mixed} \\([^\n]*, ${turn_last} on the last line before;"
   OR turn_last EQUAL 0 OR turn_last EQUAL turn_mixed OR turn_mixed EQUAL phantom_mixed)
  message(FATAL_ERROR "the printed count next to a nod turn is not ${turn_mixed} with ${turn_last} on the last line "
                      "before (of ${phantom_mixed}), or the counts do not fall strictly between 0 and the whole:\n${out}")
endif()
# Cells below the true top and against a perfect filter's map: the pooled row sums the rows, the
# printed line says the pooled numbers, the cells below also with a perfect filter fall strictly
# between 0 and all cells below, and some cells are lowered and some emptied.
set(pooled_below "")
foreach(key cells_below_true_top cells_below_true_top_unseen cells_lowered_by_false_rejections cells_emptied_by_false_rejections)
  string(JSON v GET "${json}" pooled ${key})
  string(APPEND pooled_below " ${v}")
endforeach()
if(NOT pooled_below STREQUAL " ${below} ${below_unseen} ${lowered} ${emptied}")
  message(FATAL_ERROR "cells below the true top, unseen, lowered, emptied: pooled${pooled_below}; rows sum to "
                      "${below} ${below_unseen} ${lowered} ${emptied}")
endif()
string(FIND "${out}" "cells more than 0.3 m below the lowest true top: ${below}, ${below_unseen} of them also with a perfect filter" at)
string(FIND "${out}" "cells): ${lowered} cells lowered by more than 0.3 m, ${emptied} left without a surface" at2)
if(at LESS 0 OR at2 LESS 0 OR below_unseen EQUAL 0 OR below_unseen EQUAL below OR lowered EQUAL 0 OR emptied EQUAL 0)
  message(FATAL_ERROR "the printed line does not say ${below} cells below the true top (${below_unseen} unseen), "
                      "${lowered} lowered, ${emptied} emptied, or a count is 0 or the whole:\n${out}")
endif()
message(STATUS "settings meeting each bar: ${got}; check_consistency removes ${cc_mixed} mixed, ${cc_valid} valid")
