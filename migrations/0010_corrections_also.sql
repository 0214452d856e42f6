-- gtwatch schema, version 10: a start-up two instruments' steps moved (a fuel meter reading
-- high from start-up 5, the inlet temperature from start-up 10) is corrected for both; its row
-- names the newer step's instrument, and `also` the others, as `history` prints them
-- (`fuel_meter +3.03 ± 0.25 % from start-up 6`, '; '-joined; empty: none).

ALTER TABLE instrument_corrections ADD COLUMN also TEXT NOT NULL DEFAULT '';
